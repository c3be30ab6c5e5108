"""Sum-factorised assembly of tensor-product forms straight into CSR (:mod:`.tensor`), the compiled paths for
large 3-D assemblies (:mod:`.compiled` and its kernels) and the component-major CSR of vector operators
(:mod:`.vector_csr`)."""
