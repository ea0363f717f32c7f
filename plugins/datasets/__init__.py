"""Built-in dataset plugins, one module per method."""
