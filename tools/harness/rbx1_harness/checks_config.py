"""checks_config.py - CONFIG_GET/SET/RESET: defaults, ranges, unknown keys and joints, EEPROM across a reset."""

from rbx1proto.messages import JOINTS, KEY_INFO, Key, MsgType, Status

from .board import GLOBAL, brief
from .runner import check, expect


def keys_of(is_global):
    return [k for k, info in KEY_INFO.items() if info[0] == is_global]


def snapshot(b):
    conf = {(GLOBAL, k): b.get(GLOBAL, k) for k in keys_of(True)}
    conf.update({(j, k): b.get(j, k) for j in range(JOINTS) for k in keys_of(False)})
    return conf


def restore(b, conf):
    now = snapshot(b)
    if now == conf:
        return
    # Soft limits first widened, so no intermediate SOFT_MIN > SOFT_MAX is refused.
    for j in range(JOINTS):
        b.set(j, Key.SOFT_MIN, -(2**31 - 1))
        b.set(j, Key.SOFT_MAX, 2**31 - 1)
    for (j, k), v in conf.items():
        if k not in (Key.SOFT_MIN, Key.SOFT_MAX) and now[(j, k)] != v:
            b.set(j, k, v)
    for j in range(JOINTS):
        b.set(j, Key.SOFT_MIN, conf[(j, Key.SOFT_MIN)])
        b.set(j, Key.SOFT_MAX, conf[(j, Key.SOFT_MAX)])


@check("config_defaults_ranges_errors")
def config_defaults_ranges_errors(b):
    saved = snapshot(b)  # a real board's settings come back afterwards
    try:
        b.ok(MsgType.CONFIG_RESET)
        for (j, k), _ in saved.items():
            want = KEY_INFO[k][3]
            got = b.get(j, k)
            expect(got == want, f"after CONFIG_RESET joint {j} {Key(k).name} = {got}, default {want}")
        for k, (is_global, lo, hi, _) in KEY_INFO.items():
            j = GLOBAL if is_global else 4
            if k in (Key.SOFT_MIN, Key.SOFT_MAX):
                continue  # their range depends on each other, below
            # The gripper's bounds only toward each other's side, in case the firmware keeps MIN <= MAX.
            extremes = {Key.GRIPPER_MIN_US: (lo,), Key.GRIPPER_MAX_US: (hi,)}.get(k, (lo, hi))
            for v in extremes:
                b.set(j, k, v)
                expect(b.get(j, k) == v, f"{Key(k).name} = {v} not read back")
            keep = b.get(j, k)
            for v in [x for x in (lo - 1, hi + 1) if -2**31 <= x < 2**31]:  # representable on the wire
                b.refused(MsgType.CONFIG_SET, Status.BAD_ARG, joint=j, key=k, value=v)
                expect(b.get(j, k) == keep, f"{Key(k).name}: a refused value {v} was stored")
        b.set(2, Key.SOFT_MIN, -500)
        b.set(2, Key.SOFT_MAX, 800)
        b.refused(MsgType.CONFIG_SET, Status.BAD_ARG, joint=2, key=Key.SOFT_MIN, value=801)
        b.refused(MsgType.CONFIG_SET, Status.BAD_ARG, joint=2, key=Key.SOFT_MAX, value=-501)
        expect((b.get(2, Key.SOFT_MIN), b.get(2, Key.SOFT_MAX)) == (-500, 800), "soft limits changed by refused sets")
        for joint, key in ((0, 9), (0, 0), (0, 99), (JOINTS, Key.MAX_SPEED), (GLOBAL, Key.MAX_SPEED),
                           (0, Key.HEARTBEAT_MS)):
            b.refused(MsgType.CONFIG_GET, Status.BAD_ARG, joint=joint, key=key)
            b.refused(MsgType.CONFIG_SET, Status.BAD_ARG, joint=joint, key=key, value=1000)
        b.ok(MsgType.CONFIG_RESET)
        expect(b.get(2, Key.SOFT_MAX) == KEY_INFO[Key.SOFT_MAX][3], "CONFIG_RESET did not restore SOFT_MAX")
    finally:
        restore(b, saved)


@check("config_survives_reset", control=True)
def config_survives_reset(b):
    b.set(3, Key.ACCEL, 12345)
    b.set(GLOBAL, Key.GRIPPER_MAX_US, 2222)
    try:
        b.ctl("reset")
        b.sleep(0.3)
        b.link.ser.reset_input_buffer()
        b.link.hello()
        s = b.status()
        expect(s["homed"] == 0, f"reset did not power-cycle the board: {brief(s)}")
        expect(b.get(3, Key.ACCEL) == 12345, "ACCEL of joint 4 lost across a reset")
        expect(b.get(GLOBAL, Key.GRIPPER_MAX_US) == 2222, "GRIPPER_MAX_US lost across a reset")
        expect(b.get(2, Key.ACCEL) == KEY_INFO[Key.ACCEL][3], "another joint's ACCEL changed")
    finally:
        b.set(3, Key.ACCEL, KEY_INFO[Key.ACCEL][3])
        b.set(GLOBAL, Key.GRIPPER_MAX_US, KEY_INFO[Key.GRIPPER_MAX_US][3])
