"""OpenCL devices and kernels: device discovery and ``--device`` specs (:mod:`.devices`), the kernel ABI
table from which the shared header is generated (:mod:`.abi`), arguments bound by parameter name
(:mod:`.kernel_args`), and kernel assembly and builds (:mod:`.kernels`); pip-installed OpenCL
implementations are registered by :func:`.devices.all_devices` (:mod:`.icd`).
"""
