"""Hydra config groups of the plugin, found through ``pkg://thermodrift_example_plugin.conf``."""
