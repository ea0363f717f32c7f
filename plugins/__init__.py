"""Built-in plugins. Each module registers its components through the `thermodrift` entry-point group."""
