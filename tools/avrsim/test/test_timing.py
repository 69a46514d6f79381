"""test_timing.py - step timing of the real firmware ELF (build/firmware/rbx1.elf) from rbx1-avrsim's pin-level
trace (tools/avrsim/timing.py): a short move set at the 20 kHz cap plus e-stops at random phases, checked against
the goals of issue 9. Env: AVRSIM, RBX1_FIRMWARE_ELF, RBX1_SOURCE_DIR."""
import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.realpath(__file__))))
import timing  # noqa: E402

ESTOP_TRIALS = 40
ESTOP_BOUND = 40  # cycles from the e-stop input edge to the last STEP edge (2.5 us)


@pytest.fixture(scope="module")
def figures(tmp_path_factory):
    assert os.path.exists(timing.ELF), f"{timing.ELF} missing: run tools/build-firmware"
    trace = str(tmp_path_factory.mktemp("trace") / "trace.txt")
    expected, sim = timing.run(trace, ESTOP_TRIALS)
    fig = timing.analyse(trace, expected["phases"])
    return expected, sim, fig


def test_counts_exact(figures):
    expected, sim, fig = figures
    # pins (trace), pins (avrsim's own counters) and the firmware's STATUS agree step for step
    assert fig["net_steps"] == expected["net_steps"] == sim["steps"]
    assert expected["status_ok_after_estops"]


def test_shortest_interval_at_the_cap(figures):
    _, _, fig = figures
    for j, i in enumerate(fig["min_interval_cycles"]):
        assert i is not None and i >= 0.85 * timing.CAP_INTERVAL, (j, i)


def test_step_pulse_width(figures):
    _, _, fig = figures
    assert fig["min_pulse_width_cycles"] >= 32  # pins.h: at least 2 us


def test_no_long_interrupts_off_window(figures):
    _, _, fig = figures
    # every window that can delay the step interrupt: the main loop's, the other interrupts' (UART, profile tick)
    assert fig["irq_off_window_max_cycles"] <= 100, (fig["irq_off_windows_max_cycles"], fig["irq_off_window_worst_pc"])
    assert fig["irq_off_short_windows"] > 0  # the logger saw the main loop's short guards too
    assert fig["step_isr_wait_max_cycles"] <= 110


def test_no_compare_write_behind_the_counter(figures):
    _, _, fig = figures
    assert fig["ocr1a_writes"] > 1000
    assert fig["ocr1a_late_writes"] == 0 and fig["ocr1a_min_margin_ticks"] >= 4


def test_step_isr_budget(figures):
    _, _, fig = figures
    moves = fig["step_isr_by_move"]
    assert moves["1 joint"]["cycles_per_step"] <= 150, moves["1 joint"]
    assert moves["6 joints"]["cycles_per_step"] <= 64.5, moves["6 joints"]
    assert moves["1 joint"]["pulses"] == 4000 and moves["6 joints"]["pulses"] == 24000


def test_estop_latency(figures):
    _, sim, fig = figures
    assert fig["estop_trials"] == ESTOP_TRIALS
    assert fig["estop_latency_max_cycles"] <= ESTOP_BOUND, fig["estop_latency_cycles"]
    assert sim["estop_latency_cycles"] is not None and sim["estop_latency_cycles"] <= ESTOP_BOUND
