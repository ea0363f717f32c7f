"""Built-in model plugins, one module per method."""
