"""Errors that the CLI reports as one line and a non-zero exit code (never a traceback), and the
one way the CLI reports them and the library's warnings.

The library raises :class:`UserError` subclasses for bad input and warns with
``warnings.warn`` (so that Python callers can filter or catch both); the command line shows
both through one logger, ``logging.getLogger("pyopencl_rt")``, as single lines
``pyopencl-rt: error: ...`` and ``pyopencl-rt: warning: ...`` (:func:`report_to_stderr`).
"""
import logging
import signal
import sys
import threading
import warnings

LOGGER = logging.getLogger("pyopencl_rt")


class UserError(Exception):
    """Bad input from the user: a missing file, a malformed mesh, an unknown device..."""

    exit_code = 1


class UsageError(UserError, ValueError):
    """A command (or an API call) that is wrong in itself, before any file is read: an option's
    value of the wrong type or out of its range, options that do not go together.  Also a
    ValueError, as Python code expects of a bad argument."""

    exit_code = 2


class DeviceSelectionError(UserError):
    """A --device / PYOPENCL_CTX choice that matches no OpenCL device."""

    exit_code = 2


class OutputError(UserError):
    """An output file (image, sidecar, checkpoint, benchmark JSON) that cannot be written."""


def one_line(text) -> str:
    return " ".join(str(text).split())


class _OneLine(logging.Formatter):
    def format(self, record):
        return f"pyopencl-rt: {record.levelname.lower()}: {one_line(record.getMessage())}"


class _Stderr(logging.Handler):
    """Writes to the sys.stderr of the moment (a test may have replaced it since)."""

    _pyopencl_rt = True

    def emit(self, record):
        try:
            sys.stderr.write(self.format(record) + "\n")
            sys.stderr.flush()
        except Exception:  # a closed stream must not turn a warning into a crash
            pass


_SHOW_IMPL = warnings._showwarnmsg_impl  # what shows a warning when nobody records them


def _show_warning(message, category, filename, lineno, file=None, line=None):
    if warnings._showwarnmsg_impl is not _SHOW_IMPL:  # inside catch_warnings(record=True): let it record
        warnings._showwarnmsg_impl(warnings.WarningMessage(message, category, filename, lineno, file, line))
        return
    LOGGER.warning("%s", message)


def report_to_stderr() -> None:
    """The CLI's reporting: errors and every warning (ours, and any a library lets through) as
    one line each on stderr, through :data:`LOGGER`.  Idempotent."""
    if not any(isinstance(h, _Stderr) for h in LOGGER.handlers):
        handler = _Stderr()
        handler.setFormatter(_OneLine())
        LOGGER.addHandler(handler)
    LOGGER.setLevel(logging.INFO)
    LOGGER.propagate = False
    warnings.formatwarning = lambda message, category, *args, **kwargs: f"pyopencl-rt: warning: {one_line(message)}\n"
    warnings.showwarning = _show_warning


# A Ctrl-C (SIGINT) seen by the CLI, set by watch_sigint()'s handler.  Python raises the
# KeyboardInterrupt wherever the main thread is, and where that is a callback whose exceptions are
# ignored (an import's module-lock weakref callback, during start-up) the interrupt was lost and
# the render went on to the end; render.checkpoint.stop_on_signals reads this flag, so such a
# signal still stops the render before its first pass.
SIGINT_SEEN = threading.Event()


def watch_sigint() -> None:
    """From the CLI's start: SIGINT records itself in SIGINT_SEEN, then interrupts as Python does; a
    KeyboardInterrupt that Python has to ignore (raised in such a callback) is not printed, since it
    is recorded (Python would print it with a traceback)."""

    def handler(signum, frame):
        SIGINT_SEEN.set()
        raise KeyboardInterrupt

    default_hook = sys.unraisablehook

    def unraisable(info):
        if not (isinstance(info.exc_value, KeyboardInterrupt) and SIGINT_SEEN.is_set()):
            default_hook(info)

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, handler)
        sys.unraisablehook = unraisable
