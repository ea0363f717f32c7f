"""The compensator runtime: a trained pipeline as a controller runs it, from a data-only package.

This package is the lowest layer of thermodrift: it imports numpy (scipy for physics families, torch only for
networks) and nothing of ``thermodrift.core``, MLflow or Optuna, so a controller-side PC needs none of the
training stack. Training code may import from it, so the streaming arithmetic has one home.
"""
