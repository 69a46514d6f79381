"""rbx1 - a Python client of rbx1d (the RBX1 arm's daemon): Arm(socket=...) or Arm(url=..., token=...)."""
from .arm import DEFAULT_SOCKET, Arm, Job, Watch
from .errors import *  # noqa: F401,F403 - the exception classes, one per error code
from .errors import CODES, Rbx1Error, error_from

__all__ = ["Arm", "Job", "Watch", "DEFAULT_SOCKET", "CODES", "error_from"] + [c.__name__ for c in CODES.values()] + [
    "Rbx1Error", "RequestError"]
