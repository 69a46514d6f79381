"""sim.py - starts a simulator (rbx1-simfw or rbx1-avrsim) with a private control FIFO and EEPROM file (and clock
file, on request), reads its pty path from the first stdout line, and stops it (control `quit`, then SIGTERM)."""
import os
import signal
import subprocess
import tempfile


class Simulator:
    def __init__(self, command, extra=(), clock=False):
        self.dir = tempfile.TemporaryDirectory(prefix="rbx1-harness-")
        self.control = os.path.join(self.dir.name, "control.fifo")
        os.mkfifo(self.control)
        self.eeprom = os.path.join(self.dir.name, "eeprom.bin")
        self.clock_file = os.path.join(self.dir.name, "clock") if clock else None  # written before the pty path
        self.args = [command, "--control", self.control, "--eeprom", self.eeprom,
                     *(["--clock-file", self.clock_file] if clock else []), *extra]
        self.proc = subprocess.Popen(self.args, stdout=subprocess.PIPE, text=True)
        self.port = self.proc.stdout.readline().strip()
        if not self.port.startswith("/dev/"):
            self.stop()
            raise RuntimeError(f"{command}: no pty path on its first stdout line (got {self.port!r})")

    def stop(self):
        """Returns the simulator's exit code."""
        if self.proc.poll() is None:
            try:
                fd = os.open(self.control, os.O_WRONLY | os.O_NONBLOCK)
                os.write(fd, b"quit\n")
                os.close(fd)
            except OSError:
                pass
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.send_signal(signal.SIGTERM)
                try:
                    self.proc.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait()
        self.dir.cleanup()
        return self.proc.returncode
