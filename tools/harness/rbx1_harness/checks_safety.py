"""checks_safety.py - ESTOP by message and by input, limit switches, heartbeat loss: all stop motion and latch
their fault until CLEAR_FAULT."""

from rbx1proto import frame
from rbx1proto.messages import JOINTS, Fault, Input, Key, MsgType, State, Status

from .board import brief, latching
from .checks_link import responses
from .checks_motion import LONG, start_long_move
from .runner import check, expect


def frozen(b, s, what):
    """Positions no longer change after a stop."""
    b.sleep(0.15)
    s2 = b.status()
    expect(s2["position"] == s["position"], f"still stepping after {what}: {s['position']} -> {s2['position']}")
    expect(0 < s["position"][0] < LONG[0], f"{what} did not interrupt the move: {brief(s)}")


def clears(b):
    b.ok(MsgType.CLEAR_FAULT)
    s = b.status()
    expect(s["state"] == State.IDLE and latching(s["faults"]) == 0, f"after CLEAR_FAULT: {brief(s)}")
    b.ok(MsgType.ENABLE, enable=1)
    r = b.move([0] * JOINTS)
    expect(r["status"] == Status.OK, f"MOVE after CLEAR_FAULT: {r}")
    b.wait_idle()


@check("estop_message_latches")
def estop_message_latches(b):
    start_long_move(b)
    seq, wire = b.frame(MsgType.ESTOP)
    ev = b.exchange_raw(wire, until=lambda e: responses(e, MsgType.ESTOP, seq))
    r = responses(ev, MsgType.ESTOP, seq)
    expect(len(r) == 1 and r[0].payload[0] == Status.OK, f"ESTOP: {ev}")
    s = b.status()
    expect(s["state"] == State.FAULT and s["faults"] & Fault.ESTOP_COMMAND, f"after ESTOP: {brief(s)}")
    expect(s["queue_free"] == b.queue_size, f"queue not flushed: {brief(s)}")
    frozen(b, s, "ESTOP")
    b.refused(MsgType.MOVE, Status.FAULT_ACTIVE, target=[0] * JOINTS, duration_ms=0)
    b.refused(MsgType.GRIPPER, Status.FAULT_ACTIVE, pulse_us=1500, dwell_ms=0)
    clears(b)
    # ESTOP is exempt from duplicate suppression: the very same frame (same SEQ, same CRC), sent again while the
    # arm moves after the clear, stops it and latches again.
    start_long_move(b)
    ev = b.exchange_raw(wire, until=lambda e: responses(e, MsgType.ESTOP, seq))
    r = responses(ev, MsgType.ESTOP, seq)
    expect(len(r) == 1 and r[0].payload[0] == Status.OK, f"repeated ESTOP: {ev}")
    s = b.status()
    expect(s["state"] == State.FAULT and s["faults"] & Fault.ESTOP_COMMAND, f"after the repeated ESTOP: {brief(s)}")
    frozen(b, s, "the repeated ESTOP")
    clears(b)


@check("estop_any_length_stops")
def estop_any_length_stops(b):
    # PROTOCOL.md: any CRC-valid frame whose TYPE is ESTOP stops the arm, whatever its payload length.
    for n in (1, 3, 58):
        start_long_move(b)
        seq = b.link.seq  # outside the window: echoed, not consumed
        ev = b.exchange_raw(frame.encode(seq, MsgType.ESTOP, bytes([0x5A]) * n),
                            until=lambda e: responses(e, MsgType.ESTOP, seq))
        r = responses(ev, MsgType.ESTOP, seq)
        expect(len(r) == 1 and r[0].payload == bytes([Status.OK]), f"ESTOP with {n} payload bytes: {ev}")
        s = b.status()
        expect(s["state"] == State.FAULT and s["faults"] & Fault.ESTOP_COMMAND,
               f"after an ESTOP with {n} payload bytes: {brief(s)}")
        frozen(b, s, f"an ESTOP with {n} payload bytes")
        clears(b)


@check("estop_input_latches", control=True)
def estop_input_latches(b):
    start_long_move(b)
    b.ctl("estop 1")
    s = b.wait(lambda s: s["state"] == State.FAULT, 1.0, "FAULT after the e-stop input")
    expect(s["faults"] & Fault.ESTOP_INPUT and s["inputs"] & Input.ESTOP, f"after the e-stop input: {brief(s)}")
    frozen(b, s, "the e-stop input")
    b.refused(MsgType.CLEAR_FAULT, Status.ESTOP_ACTIVE)
    b.refused(MsgType.MOVE, Status.FAULT_ACTIVE, target=[0] * JOINTS, duration_ms=0)
    b.ctl("estop 0")
    b.wait(lambda s: not s["inputs"] & Input.ESTOP, 1.0, "the e-stop input released")
    expect(b.status()["state"] == State.FAULT, "the fault did not stay latched after releasing the input")
    clears(b)


@check("limit_switch_latches", control=True)
def limit_switch_latches(b):
    b.ctl("limit 3 1")
    s = b.wait(lambda s: s["inputs"] & Input.LIMIT_J3, 1.0, "limit 3 in STATUS.inputs")
    b.ctl("limit 3 0")
    b.wait(lambda s: not s["inputs"] & Input.LIMIT_J3, 1.0, "limit 3 released")
    start_long_move(b)
    b.ctl("limit 1 1")
    s = b.wait(lambda s: s["state"] == State.FAULT, 1.0, "FAULT after a limit switch during a move")
    expect(s["faults"] & Fault.LIMIT_HIT and s["inputs"] & Input.LIMIT_J1, f"after the limit switch: {brief(s)}")
    frozen(b, s, "the limit switch")
    b.ctl("limit 1 0")
    b.wait(lambda s: not s["inputs"] & Input.LIMIT_J1, 1.0, "limit 1 released")
    clears(b)


@check("heartbeat_loss")
def heartbeat_loss(b):
    b.set(0xFF, Key.HEARTBEAT_MS, 200)
    try:
        b.sleep(0.4)  # IDLE: silence is allowed
        s = b.status()
        expect(latching(s["faults"]) == 0 and s["state"] == State.IDLE, f"heartbeat fault while IDLE: {brief(s)}")
        # Silence while MOVING must end in a controlled stop and HEARTBEAT_LOST. A simulator starved of CPU runs
        # slower than the wall clock, so without its clock (--clock-file) the silence grows until it spans 200 ms of
        # the board's own time; on its clock the first one does.
        for silence in (0.6, 1.5, 3.0, 6.0):
            r = b.move([4000, 0, 0, 0, 0, 0], 8000)  # slow: still moving when the silence ends
            expect(r["status"] == Status.OK, f"MOVE: {r}")
            b.wait(lambda s: s["position"][0] > 0 or s["state"] == State.FAULT, 2.0, "the move to start")
            b.sleep(silence)
            s = b.wait(lambda s: s["state"] != State.STOPPING, 2.0, "the controlled stop to end")
            if s["state"] == State.FAULT:
                break
            b.ok(MsgType.STOP)
            b.wait_idle()
            b.ok(MsgType.SET_POSITION, position=[0] * JOINTS)
        expect(s["state"] == State.FAULT and s["faults"] & Fault.HEARTBEAT_LOST,
               f"no HEARTBEAT_LOST after {silence} s of silence while moving: {brief(s)}")
        expect(s["queue_free"] == b.queue_size, f"queue not flushed: {brief(s)}")
        expect(0 < s["position"][0] < 4000, f"the move was not interrupted: {brief(s)}")
        b.sleep(0.15)
        expect(b.status()["position"] == s["position"], "still stepping after heartbeat loss")
        clears(b)
    finally:
        b.rest()
        b.set(0xFF, Key.HEARTBEAT_MS, 1000)
