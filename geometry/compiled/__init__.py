"""Compiled kernels (numba; imported only when installed and first needed) and the lock that compiles each
once among processes starting together.  Every kernel has a NumPy path used where numba is absent."""
