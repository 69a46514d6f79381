// link_errors.cpp - the link's negative errnos in words, with what to do: no user reads a bare "-110".
#include "link.hpp"

#include <cerrno>
#include <cstring>

namespace rbx1::link {

std::string error_text(int r) {
  switch (-r) {
    case ETIMEDOUT: return "no answer from the firmware after every retransmission (check the cable and the board's power)";
    case ENODEV:
    case EIO: return "the serial port went away (unplugged or reset; the daemon reconnects when it is back)";
    case ENOENT: return "no such serial port (check [link] port, --port or RBX1_PORT, and that the board is plugged in)";
    case ENOTCONN: return "the link is not open (the firmware has not answered HELLO yet)";
    case EBUSY: return "the serial port is in use by another program";
    case EPROTO: return "the firmware speaks another protocol version (flash the matching firmware: rbx1-flash)";
    case EBADMSG: return "an answer of the wrong length (a firmware of another version? rbx1-flash)";
    case EOPNOTSUPP: return "the firmware does not know this request (an older firmware? rbx1-flash)";
    default: return r < 0 ? std::strerror(-r) : "no error";
  }
}

std::string failed(const std::string& port, const std::string& what, int r) {
  return port + ": " + what + " failed: " + error_text(r);
}

}  // namespace rbx1::link
