"""OpenCL devices and kernels: device discovery and ``--device`` specs (:mod:`.devices`), the kernel ABI
table from which the shared header is generated (:mod:`.abi`), and kernel assembly and builds (:mod:`.kernels`).
"""
