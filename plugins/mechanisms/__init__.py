"""Built-in mechanism plugins, one module per method."""
