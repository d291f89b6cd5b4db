"""The link to the rover: framing, messages, transports and the Link that ties them."""
