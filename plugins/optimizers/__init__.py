"""Built-in optimizer plugins, one module per method."""
