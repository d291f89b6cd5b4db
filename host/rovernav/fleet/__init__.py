"""A fleet: several rovers under one camera on one radio (issue 30; docs/design.md)."""
