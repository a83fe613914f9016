"""Compiled (Cython) kernels of the planner's modules; built by setup.py."""
