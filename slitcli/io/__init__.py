"""Input and output: atomic writes, stereo sequences, bags and tables."""
