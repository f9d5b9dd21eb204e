"""OpenCL devices and kernels: device discovery and ``--device`` specs (:mod:`.devices`), the kernel ABI
table from which the shared header is generated (:mod:`.abi`), arguments bound by parameter name
(:mod:`.kernel_args`), and kernel assembly and builds (:mod:`.kernels`).
"""
from .icd import register as _register_packaged_icds

# before pyopencl's ICD loader reads $OCL_ICD_VENDORS (its first call): pip-installed runtimes
_register_packaged_icds()
