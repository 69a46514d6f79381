"""rbx1proto - the RBX1 link protocol in Python: framing (frame), messages (messages, generated), and a serial Link."""
from . import frame, messages  # noqa: F401  (link imports pyserial lazily: import rbx1proto.link when needed)
