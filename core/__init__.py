"""thermodrift's framework: registry, recordings, splits, metrics, studies, tracking and the CLI."""
