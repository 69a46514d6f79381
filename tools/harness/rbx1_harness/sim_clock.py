"""sim_clock.py - a simulated board's clock, read through the file it maps (rbx1-avrsim and rbx1-avrboard
--clock-file; the layout is tools/simpty/clock_file.hpp's): bytes 0-7 the simulated cycles (u64 little-endian, an
atmega2560 at 16 MHz), byte 8 the host's busy flag (rbx1-avrsim --hold-for-host)."""
import mmap
import struct

HZ = 16_000_000


class SimClock:
    def __init__(self, path):
        """Maps `path`, which the simulator creates before it prints its pty path."""
        with open(path, "r+b") as f:
            self._map = mmap.mmap(f.fileno(), 16)
        self.busy = memoryview(self._map)[8:9]  # 1 while the host decides or writes (HostTurn in tools/avrsim)

    def seconds(self):
        """Simulated seconds since the simulator started."""
        return struct.unpack_from("<Q", self._map, 0)[0] / HZ

    def close(self):
        self.busy.release()
        self._map.close()
