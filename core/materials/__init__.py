"""Core BSDFs: one module per family. Each offers ``eval``, ``sample`` and ``pdf`` on batches."""
