"""rovernav: guide a small rover through a partially unknown arena from an overhead camera."""
__version__ = "0.1.0"
