"""Sampling: warps (sample/pdf/invert triples), discrete distributions, sample streams."""
