"""Kernel arguments set by parameter name, from a parameter table of :mod:`.abi`.

Kernels that share a parameter list (the wavefront stages share :data:`abi.WAVE_PARAMS`) get
their arguments by name, never by position: the position comes from the table, which also
generates the kernels' signatures, so host and device cannot disagree on the order.
"""
from __future__ import annotations

from . import abi


class KernelArgs:
    """The arguments of ``kernels`` (a dict name -> pyopencl Kernel) that take ``params``."""

    def __init__(self, kernels: dict, params=abi.WAVE_PARAMS):
        self.kernels = kernels
        self.params = tuple(params)
        self.index = {p.name: i for i, p in enumerate(self.params)}
        self.values: dict = {}

    def _value(self, name, value):
        try:
            p = self.params[self.index[name]]
        except KeyError:
            raise KeyError(f"{name!r} is not a kernel parameter") from None
        return p.scalar(value) if p.kind == "scalar" else value

    def bind(self, **values) -> None:
        """Set arguments on every kernel (scalars converted to the parameter's C type)."""
        for name, value in values.items():
            value = self.values[name] = self._value(name, value)
            i = self.index[name]
            for k in self.kernels.values():
                k.set_arg(i, value)

    def set(self, kernel: str, **values) -> None:
        """Set arguments on one kernel only (per-launch arguments)."""
        k = self.kernels[kernel]
        for name, value in values.items():
            k.set_arg(self.index[name], self._value(name, value))

    def __getitem__(self, name):
        """The value bound to ``name`` by :meth:`bind` (a buffer, or a numpy scalar)."""
        return self.values[name]

    def unbound(self) -> list[str]:
        """Parameters that :meth:`bind` has not set."""
        return [p.name for p in self.params if p.name not in self.values]
