"""Errors that the CLI reports as one line and a non-zero exit code (never a traceback)."""


class UserError(Exception):
    """Bad input from the user: a missing file, a malformed mesh, an unknown device..."""

    exit_code = 1


class DeviceSelectionError(UserError):
    """A --device / PYOPENCL_CTX choice that matches no OpenCL device."""

    exit_code = 2
