"""Compiled (Cython) kernels of the stereo matcher; built by setup.py."""
