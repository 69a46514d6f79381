"""flip_proxy.py - a serial line that corrupts an upload in transit: a pty that avrdude opens, forwarding to the
simulated board's pty, that flips bit 0 of the first two data bytes of the first flash page avrdude programs.
Two equal bit flips leave the stk500v2 message's XOR checksum valid, so the bootloader writes the wrong bytes and
only avrdude's read-back verify can notice."""
import os
import select
import termios
import threading
import time
import tty

MESSAGE_START, TOKEN, CMD_PROGRAM_FLASH_ISP = 0x1B, 0x0E, 0x13
DATA_OFFSET = 10  # body: cmd, NumBytes (2), mode, delay, cmd1..3, poll1, poll2, then the data


def open_resetting(path):
    """Opens the board's port so that the open resets it (HUPCL set first, as tools/flash does with stty)."""
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    attrs = termios.tcgetattr(fd)
    attrs[2] |= termios.HUPCL
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    os.close(fd)  # the last close with HUPCL drops DTR
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)  # asserting it again is the reset
    tty.setraw(fd)
    return fd


class FlipProxy:
    def __init__(self, board_port):
        self.board_port = board_port
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # kept open: the master never reads EIO between clients
        self.port = os.ttyname(self.slave)
        self.board = None
        self.flipped_at = None  # the flash byte address whose page was corrupted
        self.pending = bytearray()
        self.address = 0  # from CMD_LOAD_ADDRESS, in words
        self.stop_r, self.stop_w = os.pipe()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def close(self):
        os.write(self.stop_w, b"x")
        self.thread.join(5)
        for fd in (self.master, self.slave, self.stop_r, self.stop_w) + ((self.board,) if self.board else ()):
            os.close(fd)

    def _messages(self):
        """Splits pending host bytes into whole stk500v2 messages (corrupting the first page write) and passes
        anything else through as it is."""
        out = bytearray()
        buf = self.pending
        while buf:
            if buf[0] != MESSAGE_START:
                out.append(buf.pop(0))
                continue
            if len(buf) < 5:
                break
            size = (buf[2] << 8) | buf[3]
            if buf[4] != TOKEN or size > 300:
                out.append(buf.pop(0))
                continue
            if len(buf) < 6 + size:
                break
            msg = buf[:6 + size]
            del buf[:6 + size]
            body = msg[5:5 + size]
            if body[0] == 0x06 and size >= 5:  # CMD_LOAD_ADDRESS: big-endian word address, bit 31 = extended
                self.address = int.from_bytes(body[1:5], "big") & 0x7FFFFFFF
            if body[0] == CMD_PROGRAM_FLASH_ISP and self.flipped_at is None and size > DATA_OFFSET + 1:
                msg[5 + DATA_OFFSET] ^= 0x01
                msg[5 + DATA_OFFSET + 1] ^= 0x01
                self.flipped_at = self.address * 2
            out += msg
        return bytes(out)

    def _run(self):
        while True:
            fds = [self.master, self.stop_r] + ([self.board] if self.board is not None else [])
            ready, _, _ = select.select(fds, [], [])
            if self.stop_r in ready:
                return
            if self.master in ready:
                data = os.read(self.master, 4096)
                if self.board is None:
                    self.board = open_resetting(self.board_port)  # avrdude's first bytes: the port "opened"
                    # Bytes written in the same instant as the reset can reach the application before the reset
                    # takes effect and be lost; the bootloader listens for 0.83 s, so let it start first (avrdude
                    # itself waits after its own DTR pulse on a real port).
                    time.sleep(0.1)
                self.pending += data
                os.write(self.board, self._messages())
            if self.board is not None and self.board in ready:
                os.write(self.master, os.read(self.board, 4096))
