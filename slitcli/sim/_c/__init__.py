"""Compiled (Cython) kernels of the renderer; built by setup.py."""
