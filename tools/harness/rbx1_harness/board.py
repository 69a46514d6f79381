"""board.py - the device under test as the checks see it: requests through rbx1proto's Link, raw frames on the
wire, STATUS polling, the simulator's control FIFO, and a known starting state before every check."""
import os
import time

from rbx1proto import frame, messages
from rbx1proto.link import Link, LinkError
from rbx1proto.messages import JOINTS, Fault, MsgType, State, Status

from .runner import expect
from .sim_clock import SimClock

POLL_S = 0.02
GLOBAL = messages.GLOBAL_JOINT


class Board:
    def __init__(self, port, baud=115200, control=None, timeout=0.3, retries=10, boot_wait=0.0, clock_file=None):
        self.port, self.baud = port, baud
        self.clock_slack = 0.0  # how far the device's clock may lag the wall clock and then catch up (--clock-slack)
        # The device's own clock when a simulator shares it (--clock-file: its simulated cycles): every timeout,
        # silence and duration of the checks is then counted on it, so a simulator that a loaded machine holds
        # behind real time is neither timed out early nor left silent for less of its time than a check meant.
        self.sim_clock = SimClock(clock_file) if clock_file else None
        # More patient than a host must be (100 ms, 5 retransmissions): the checks test the device, and a busy test
        # machine can deschedule this process past 100 ms. The answer time itself is checked in response_time.
        self.link = Link(port, baudrate=baud, timeout=timeout, retries=retries)
        self.link.clock = self.now
        self.control_path = control
        self.control = None
        if control:
            # O_NONBLOCK fails with ENXIO until the simulator has opened its end: wait for it briefly.
            for _ in range(100):
                try:
                    self.control = os.fdopen(os.open(control, os.O_WRONLY | os.O_NONBLOCK), "w")
                    break
                except OSError:
                    time.sleep(0.05)
            expect(self.control is not None, f"{control}: no simulator reads this control FIFO")
        # Opening a Mega's port (DTR) may have reset it: its stk500v2 bootloader takes a byte arriving in its first
        # 0.83 s as an upload starting, and then stays until 5.2 s pass without one (tools/flashsim/README.md).
        self.sleep(boot_wait)
        try:
            self.info = self.link.hello()
        except LinkError as e:
            expect("protocol version 3" not in str(e), f"{e}: flash the matching firmware: make flash PORT={port} "
                                                        f"(installed: rbx1-flash {port})")
            raise
        theirs = self.info["proto_version"]
        expect(self.info["status"] != Status.BAD_VERSION and theirs == messages.PROTO_VERSION,
               f"the firmware speaks protocol version {theirs}, this harness {messages.PROTO_VERSION}: flash the "
               f"matching firmware: make flash PORT={port} (installed: rbx1-flash {port})")
        self.queue_size = self.info["queue_size"]
        self.saved_config = None

    def close(self):
        self.link.close()
        if self.control:
            self.control.close()
        if self.sim_clock:
            self.sim_clock.close()

    # --- the device's clock ---------------------------------------------------------------------------------
    def now(self):
        """Seconds on the device's clock: the simulator's (--clock-file), else the wall clock (a real board's and
        rbx1-simfw's clocks keep it)."""
        if self.sim_clock:
            return self.sim_clock.seconds()
        return time.monotonic()

    def sleep(self, seconds):
        """Silence of `seconds` on the device's clock."""
        if not self.sim_clock:
            time.sleep(seconds)
            return
        end = self.now() + seconds
        while (left := end - self.now()) > 0:
            time.sleep(min(left, 0.005))

    # --- requests -------------------------------------------------------------------------------------------
    def req(self, msg_type, **fields):
        return self.link.request(msg_type, **fields)

    def ok(self, msg_type, **fields):
        """A request that must succeed; returns its response."""
        r = self.req(msg_type, **fields)
        expect(r["status"] == Status.OK, f"{MsgType(msg_type).name} {fields or ''}: {status_name(r['status'])}")
        return r

    def refused(self, msg_type, want, **fields):
        """A request that must be refused with status want."""
        r = self.req(msg_type, **fields)
        expect(r["status"] == want, f"{MsgType(msg_type).name} {fields or ''}: expected {status_name(want)}, "
                                    f"got {status_name(r['status'])}")
        return r

    def status(self):
        return self.ok(MsgType.STATUS)

    def move(self, target, duration_ms=0):
        return self.req(MsgType.MOVE, target=list(target), duration_ms=duration_ms)

    def get(self, joint, key):
        r = self.ok(MsgType.CONFIG_GET, joint=joint, key=key)
        return r["value"]

    def set(self, joint, key, value):
        self.ok(MsgType.CONFIG_SET, joint=joint, key=key, value=value)

    # --- waiting --------------------------------------------------------------------------------------------
    def wait(self, pred, timeout, what):
        """Polls STATUS (which also feeds the heartbeat) until pred(status) holds; returns that status."""
        end = self.now() + timeout
        while True:
            s = self.status()
            if pred(s):
                return s
            expect(self.now() < end, f"timed out after {timeout} s waiting for {what}; last STATUS {brief(s)}")
            time.sleep(POLL_S)

    def wait_idle(self, timeout=10.0):  # generous: a simulator on a busy host can run well below real time
        return self.wait(lambda s: s["state"] == State.IDLE and s["queue_free"] == self.queue_size,
                         timeout, "IDLE with an empty queue")

    def wait_state(self, state, timeout=3.0):
        return self.wait(lambda s: s["state"] == state, timeout, State(state).name)

    def rest(self):
        """Cleanup after a check, whatever its outcome: motion stopped, faults cleared; raises nothing of its own
        so the check's own failure is the one reported."""
        try:
            self.req(MsgType.STOP)
            end = self.now() + 5.0
            while self.status()["state"] not in (State.IDLE, State.FAULT) and self.now() < end:
                time.sleep(POLL_S)
            self.req(MsgType.CLEAR_FAULT)
        except (AssertionError, LinkError):
            pass

    # --- control FIFO (simulators only) -----------------------------------------------------------------------
    def ctl(self, line):
        self.control.write(line + "\n")
        self.control.flush()

    # --- raw frames -----------------------------------------------------------------------------------------
    def next_seq(self):
        seq = self.link.seq
        self.link.seq = (seq + 1) & 0xFF
        return seq

    def frame(self, msg_type, seq=None, **fields):
        """(seq, wire bytes) of a request frame, consuming the next SEQ unless one is given (an ESTOP takes the next
        SEQ without consuming it: it has no place in the firmware's order)."""
        if seq is None:
            seq = self.link.seq if msg_type == MsgType.ESTOP else self.next_seq()
        return seq, frame.encode(seq, msg_type, messages.pack_request(msg_type, **fields))

    def exchange_raw(self, data, until=None, timeout=0.4):
        """Writes bytes as they are and collects what comes back (Frames and Rejects) until until(events) holds
        or timeout passes."""
        ser = self.link.ser
        ser.reset_input_buffer()
        self.link.send_raw(data)
        dec = frame.Decoder()
        events = []
        end = self.now() + timeout
        while self.now() < end:
            ser.timeout = max(0.001, end - self.now())
            b = ser.read(1)
            if b:
                events += dec.feed(b + ser.read(ser.in_waiting))
                if until and until(events):
                    break
        return events

    # --- a known state before every check -------------------------------------------------------------------
    def prepare(self):
        """Releases simulated inputs, stops motion, clears faults, enables the drivers and declares all joints at 0."""
        if self.control:
            self.ctl("estop 0")
            for j in range(1, 7):
                self.ctl(f"limit {j} 0")
        self.link.ser.reset_input_buffer()
        self.link.decoder = frame.Decoder()
        self.link.hello()
        s = self.status()
        if s["state"] in (State.MOVING, State.HOMING):
            self.ok(MsgType.STOP)
        self.wait(lambda s: s["state"] in (State.IDLE, State.FAULT), 5.0, "motion to end")
        self.ok(MsgType.CLEAR_FAULT)
        self.ok(MsgType.ENABLE, enable=1)
        self.ok(MsgType.SET_POSITION, position=[0] * JOINTS)


def status_name(code):
    try:
        return Status(code).name
    except ValueError:
        return f"status {code}"


def brief(s):
    """A STATUS response in one readable line."""
    try:
        state = State(s["state"]).name
    except ValueError:
        state = str(s["state"])
    return (f"state={state} faults={Fault(s['faults'])!r} homed={s['homed']:#04x} inputs={s['inputs']:#04x} "
            f"enabled={s['enabled']} queue_free={s['queue_free']} moves_done={s['moves_done']} "
            f"gripper_us={s['gripper_us']} position={s['position']}")


def latching(faults):
    return faults & messages.FAULTS_LATCHING


__all__ = ["Board", "GLOBAL", "brief", "latching", "status_name"]
