"""checks_motion.py - moves to exact step targets, timing, queue flow control, gripper, STOP, soft limits,
requests refused while moving, disabled drivers, not-homed refusal and homing against a simulated switch."""

from rbx1proto.messages import ALL_JOINTS_MASK, JOINTS, Key, MsgType, State, Status

from .board import brief, latching
from .runner import check, expect

LONG = [2000, 0, 0, 0, 0, 0]  # with LONG_MS, a slow move to interrupt
LONG_MS = 2000
HEAD_MS = 4000  # queue_flow_control's first move: the queue fills behind it


def start_long_move(b):
    r = b.move(LONG, LONG_MS)
    expect(r["status"] == Status.OK, f"MOVE: {r}")
    return b.wait(lambda s: s["position"][0] > 0, 3.0, "the move to start")  # patient: avrsim on a loaded host


@check("move_exact_targets")
def move_exact_targets(b):
    before = b.status()
    targets = [[400, -300, 250, -200, 150, -100], [-150, 320, 0, 75, -75, 600], [0, 0, 0, 0, 0, 0]]
    for t in targets:
        r = b.move(t)
        expect(r["status"] == Status.OK, f"MOVE {t}: {r}")
    s = b.status()
    expect(s["state"] == State.MOVING, f"not MOVING with moves queued: {brief(s)}")
    s = b.wait_idle()
    expect(s["moves_done"] == (before["moves_done"] + 3) & 0xFFFF, f"moves_done {s['moves_done']}: expected +3")
    expect(s["position"] == targets[-1], f"ended at {s['position']}")
    r = b.move([-1234, 0, 77, 0, 0, 1])
    expect(r["status"] == Status.OK, f"MOVE: {r}")
    s = b.wait_idle()
    expect(s["position"] == [-1234, 0, 77, 0, 0, 1], f"ended at {s['position']}, not at the targets")


@check("move_duration_honoured")
def move_duration_honoured(b):
    t0 = b.now()
    r = b.move([100, 50, 0, 0, 0, 0], 600)
    expect(r["status"] == Status.OK, f"MOVE: {r}")
    s = b.wait_idle()
    took = b.now() - t0
    # Lower bound, exact: the firmware completes an entry after duration_ms profile ticks (1 ms each) counted from
    # the tick that starts it, so never sooner than 599 ms of its clock after its frame arrived, and t0 was taken
    # before the frame was sent. A real board's and rbx1-simfw's clocks never lag the wall clock, and a simulator
    # that shares its clock (--clock-file) is timed on it; one that does not may fall behind the wall clock on a
    # loaded host and catch up, which shortens the wall time by at most that lag (--clock-slack). The upper bound is the host's, not the firmware's: a loaded machine slows the simulators
    # (rbx1-avrsim ran a 600 ms move in 1.79 s of wall time at a load of 18 on 2 cores) and the polling, so it only
    # catches a firmware that ignores duration_ms by far.
    low = 0.599 - (0 if b.sim_clock else b.clock_slack)
    expect(low <= took <= 4.0, f"a 600 ms move took {took:.3f} s (0.6 s expected: at least {low:.3f}, at most 4)")
    expect(s["position"][:2] == [100, 50], f"ended at {s['position']}")


@check("queue_flow_control")
def queue_flow_control(b):
    # The first move takes HEAD_MS: nothing leaves the queue while it fills, however slow the host's exchanges (a
    # loaded machine once let three 150 ms moves end while the host sent the others). The heartbeat is raised
    # meanwhile: a host held up for a second by the load is not what this check is about (heartbeat_loss is).
    heartbeat = b.get(0xFF, Key.HEARTBEAT_MS)
    b.set(0xFF, Key.HEARTBEAT_MS, 10000)
    try:
        before = b.status()
        accepted, refused, queue_free = 0, None, []
        for i in range(2 * b.queue_size + 4):
            target = [10 * (i + 1), 0, 0, 0, 0, 0]
            r = b.move(target, HEAD_MS if i == 0 else 150)
            if r["status"] == Status.QUEUE_FULL:
                refused = target
                break
            expect(r["status"] == Status.OK, f"MOVE {i}: {r}; {brief(b.status())}")
            accepted += 1
            queue_free.append(r["queue_free"])
        expect(refused is not None, f"{accepted} moves accepted with a queue of {b.queue_size}: no QUEUE_FULL")
        expect(accepted == b.queue_size, f"{accepted} moves accepted with a queue of {b.queue_size}")
        expect(queue_free == list(range(b.queue_size - 1, -1, -1)), f"queue_free in the MOVE responses: {queue_free}")
        expect(b.status()["queue_free"] == 0, "STATUS.queue_free is not 0 with the queue full")
        b.wait(lambda s: s["queue_free"] > 0, HEAD_MS / 1000 + 10, "room in the queue")
        r = b.move(refused, 150)
        expect(r["status"] == Status.OK, f"the refused MOVE, retried after a move finished: {r}")
        s = b.wait_idle(timeout=10 + 0.2 * accepted)
        expect(s["moves_done"] == (before["moves_done"] + accepted + 1) & 0xFFFF, f"moves_done {s['moves_done']}")
        expect(s["position"][0] == refused[0], f"ended at {s['position']}, expected {refused[0]}")
    finally:
        b.set(0xFF, Key.HEARTBEAT_MS, heartbeat)


@check("gripper")
def gripper(b):
    before = b.status()
    lo, hi = b.get(0xFF, Key.GRIPPER_MIN_US), b.get(0xFF, Key.GRIPPER_MAX_US)
    pulse = (lo + hi) // 2 + 7
    r = b.req(MsgType.GRIPPER, pulse_us=pulse, dwell_ms=100)
    expect(r["status"] == Status.OK, f"GRIPPER: {r}")
    s = b.wait_idle()
    expect(s["gripper_us"] == pulse, f"gripper_us {s['gripper_us']} != {pulse}")
    expect(s["moves_done"] == (before["moves_done"] + 1) & 0xFFFF, f"moves_done {s['moves_done']}: expected +1")
    b.refused(MsgType.GRIPPER, Status.BAD_ARG, pulse_us=lo - 1, dwell_ms=0)
    b.refused(MsgType.GRIPPER, Status.BAD_ARG, pulse_us=hi + 1, dwell_ms=0)
    expect(b.status()["moves_done"] == s["moves_done"], "a refused GRIPPER was queued")


@check("stop_controlled")
def stop_controlled(b):
    start_long_move(b)
    b.move([2000, 100, 0, 0, 0, 0])  # a second entry, flushed by STOP
    b.ok(MsgType.STOP)
    s = b.wait_idle()
    expect(0 < s["position"][0] < LONG[0], f"STOP did not stop the move: {brief(s)}")
    expect(s["position"][1] == 0, "the queued entry ran after STOP")
    expect(latching(s["faults"]) == 0, f"STOP latched a fault: {brief(s)}")
    b.sleep(0.1)
    expect(b.status()["position"] == s["position"], "still moving after STOP")
    r = b.move([0] * JOINTS)
    expect(r["status"] == Status.OK, f"MOVE after STOP: {r}")
    b.wait_idle()


@check("soft_limits")
def soft_limits(b):
    before = b.status()
    for t in ([100001, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, -100001], [0, 0, 2**31 - 1, 0, 0, 0]):
        r = b.move(t)
        expect(r["status"] == Status.SOFT_LIMIT, f"MOVE {t}: expected SOFT_LIMIT, got {r}")
    b.set(1, Key.SOFT_MAX, 500)
    try:
        r = b.move([0, 501, 0, 0, 0, 0])
        expect(r["status"] == Status.SOFT_LIMIT, f"MOVE beyond a configured SOFT_MAX: {r}")
        s = b.status()
        expect(s["queue_free"] == b.queue_size and s["moves_done"] == before["moves_done"], "a refused MOVE was queued")
        r = b.move([0, 500, 0, 0, 0, 0])
        expect(r["status"] == Status.OK, f"MOVE to SOFT_MAX: {r}")
        s = b.wait_idle()
        expect(s["position"][1] == 500, f"ended at {s['position']}")
        # SET_POSITION declares only positions the firmware could move to: outside, refused, nothing changes.
        for p in ([0, 501, 0, 0, 0, 0], [-100001, 0, 0, 0, 0, 0]):
            b.refused(MsgType.SET_POSITION, Status.SOFT_LIMIT, position=p)
        expect(b.status()["position"] == s["position"], "a refused SET_POSITION changed the position")
        b.ok(MsgType.SET_POSITION, position=[0, 500, 0, 0, 0, 0])
    finally:
        b.rest()
        b.set(1, Key.SOFT_MAX, 100000)


@check("busy_while_moving")
def busy_while_moving(b):
    start_long_move(b)
    b.refused(MsgType.SET_POSITION, Status.BUSY, position=[0] * JOINTS)
    b.refused(MsgType.HOME, Status.BUSY, joint_mask=0)
    b.refused(MsgType.ENABLE, Status.BUSY, enable=0)
    b.refused(MsgType.CONFIG_SET, Status.BUSY, joint=0, key=Key.MAX_SPEED, value=1000)
    b.refused(MsgType.CONFIG_RESET, Status.BUSY)
    r = b.ok(MsgType.CONFIG_GET, joint=0, key=Key.MAX_SPEED)  # reading is fine
    expect(r["value"] > 0, f"CONFIG_GET {r}")
    s = b.status()
    expect(s["state"] == State.MOVING and s["enabled"] == 1, f"a refused request changed the state: {brief(s)}")
    b.ok(MsgType.STOP)
    b.wait_idle()


@check("disabled_refused")
def disabled_refused(b):
    b.ok(MsgType.ENABLE, enable=0)
    s = b.status()
    expect(s["enabled"] == 0, f"ENABLE 0 not reflected: {brief(s)}")
    b.refused(MsgType.MOVE, Status.DISABLED, target=[10, 0, 0, 0, 0, 0], duration_ms=0)
    b.refused(MsgType.ENABLE, Status.BAD_ARG, enable=2)
    b.ok(MsgType.ENABLE, enable=1)
    r = b.move([10, 0, 0, 0, 0, 0])
    expect(r["status"] == Status.OK, f"MOVE after ENABLE 1: {r}")
    expect(b.wait_idle()["position"][0] == 10, "did not reach 10")


@check("not_homed_after_power_up", control=True)
def not_homed_after_power_up(b):
    b.ctl("reset")
    b.sleep(0.3)
    b.link.ser.reset_input_buffer()
    b.link.hello()
    s = b.status()
    expect(s["homed"] == 0 and s["enabled"] == 0 and s["state"] == State.IDLE, f"power-up state: {brief(s)}")
    b.ok(MsgType.ENABLE, enable=1)
    b.refused(MsgType.MOVE, Status.NOT_HOMED, target=[0] * JOINTS, duration_ms=0)
    b.refused(MsgType.GRIPPER, Status.NOT_HOMED, pulse_us=1500, dwell_ms=0)
    b.ok(MsgType.SET_POSITION, position=[5, 0, 0, 0, 0, 0])
    expect(b.status()["homed"] == ALL_JOINTS_MASK, "SET_POSITION did not mark the joints homed")
    r = b.move([0] * JOINTS)
    expect(r["status"] == Status.OK, f"MOVE once declared: {r}")
    b.wait_idle()


@check("homing_with_switch", control=True)
def homing_with_switch(b):
    home = 777
    b.set(0, Key.HOME_POSITION, home)
    try:
        b.ok(MsgType.HOME, joint_mask=0x01)
        s = b.wait(lambda s: s["position"][0] < -20, 2.0, "joint 1 to seek its switch (HOME_DIR 0: towards min)")
        expect(s["state"] == State.HOMING and not s["homed"] & 1, f"while seeking: {brief(s)}")
        b.ctl("limit 1 1")
        at_switch = b.wait(lambda s: s["inputs"] & 1, 1.0, "the switch in STATUS.inputs")["position"][0]
        # It backs off the switch; release the switch once it moves away, as a real one would.
        b.wait(lambda s: s["position"][0] >= at_switch + 3 or s["state"] != State.HOMING, 3.0, "the back-off")
        b.ctl("limit 1 0")
        s = b.wait(lambda s: s["state"] != State.HOMING, 3.0, "homing to finish")
        expect(s["state"] == State.IDLE and latching(s["faults"]) == 0, f"after homing: {brief(s)}")
        expect(s["homed"] & 1, f"joint 1 not marked homed: {brief(s)}")
        # Exact: the joint's position is set to HOME_POSITION at rest, where the back-off jog stopped on the release.
        expect(s["position"][0] == home, f"position {s['position'][0]} after homing, HOME_POSITION {home}")
    finally:
        b.rest()
        b.set(0, Key.HOME_POSITION, 0)
