"""Applications: the command line, the demo and batch processing. Nothing imports this layer."""
