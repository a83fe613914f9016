"""Compiled (Cython) kernels of the laser stripe search; built by setup.py."""
