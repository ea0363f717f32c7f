"""Built-in selector plugins, one module per method."""
