"""Hydra sweeper plugin: sweeps any Hydra app with thermodrift's Optuna samplers."""
