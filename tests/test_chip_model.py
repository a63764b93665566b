"""The chip model (tactilize.boardhost.rp2040) against the RP2040's rules, each
expectation worked out by hand from docs/references.md, section 10 (the chip
model): a 125 MHz system clock, so at DIV 1.0 a count lasts 8 ns; a period is
(TOP + 1) counts; an output is high while the counter is below its compare."""

from __future__ import annotations

import pytest

from tactilize.boardhost import rp2040 as R
from tactilize.boardhost.rp2040_machine import Machine
from tactilize.boardhost.virtual_board import VirtualBoard


class Clock:
    def __init__(self) -> None:
        self.us = 0.0

    def __call__(self) -> float:
        return self.us


def _chip(timer_us: int = 0) -> tuple[R.Chip, Machine, Clock]:
    clock = Clock()
    chip = R.Chip(clock, timer_us=timer_us)
    return chip, Machine(chip), clock


def _approx(pulses):
    return [(pytest.approx(s, abs=1e-6), pytest.approx(w, abs=1e-6)) for s, w in pulses]


def test_ticks_wrap_at_2_30_and_differ_signed():
    chip, m, clock = _chip(timer_us=(1 << 30) - 1000)
    assert m.ticks_us() == (1 << 30) - 1000
    clock.us = 2000
    assert m.ticks_us() == 1000
    assert R.ticks_diff(1000, (1 << 30) - 1000) == 2000
    assert R.ticks_diff(0, 1 << 29) == -(1 << 29)
    assert R.ticks_add((1 << 30) - 1, 1) == 0
    assert R.ticks_add(5, (1 << 29) - 1) == 5 + (1 << 29) - 1
    for bad in (1 << 29, -(1 << 29)):
        with pytest.raises(OverflowError, match="ticks interval overflow"):
            R.ticks_add(0, bad)


def test_a_compare_written_mid_period_takes_effect_at_the_wrap():
    chip, m, clock = _chip()
    chip.sio(0, func="pwm")
    # TOP 999 at DIV 1: 8 us periods; compare 250: 2 us high
    chip.pwm_write(0, div16=16, top=999, cc=(0, 250), en=True)
    clock.us = 3.0  # counter at 375: below the new compare, above the old one
    chip.pwm_write(0, cc=(0, 500))
    clock.us = 24.0
    # no second pulse in the first period: the new compare waits for the wrap at 8 us
    assert chip.pulses_us(0) == _approx([(0.0, 2.0), (8.0, 4.0), (16.0, 4.0)])


def test_a_slice_stopped_before_its_wrap_resumes_its_count_at_the_new_divider():
    chip, m, clock = _chip()
    chip.sio(0, func="pwm")
    chip.pwm_write(0, div16=16, top=999, cc=(0, 250), en=True)
    clock.us = 7.504  # 938 counts of 8 ns: stopped 62 counts before the wrap
    chip.pwm_write(0, en=False)
    clock.us = 20.0
    chip.pwm_write(0, div16=32, en=True)  # DIV 2.0: 16 ns per count, at once
    clock.us = 60.0
    # the first period after the restart is the 62 counts left: 0.992 us, low
    # (938 > 250); then 16 us periods with 4 us pulses from 20.992 us
    assert chip.pulses_us(0) == _approx([(0.0, 2.0), (20.992, 4.0), (36.992, 4.0), (52.992, 4.0)])
    chip.slices[0].advance(chip.t_h())
    assert chip.slices[0].ctr == 438  # 7.008 us into the period at 16 ns a count


def test_a_stopped_slice_holds_its_output_and_micropython_keeps_its_counter():
    chip, m, clock = _chip()
    pwm = m.PWM(m.Pin(16))
    assert not chip.slices[0].en  # PWM(pin) alone starts nothing
    pwm.freq(1000)
    pwm.duty_ns(500_000)  # freq and duty set: MicroPython enables the slice
    assert chip.slices[0].en
    clock.us = 1200.25  # in the second pulse
    pwm.deinit()
    ctr = chip.slices[0].ctr
    assert chip.level(16) == 1  # stopped mid-pulse: held high
    again = m.PWM(m.Pin(16))
    assert chip.slices[0].ctr == ctr and not chip.slices[0].en
    again.duty_u16(0)  # the slice's frequency is still set: this starts it at once
    assert chip.slices[0].en
    m.Pin(16, m.Pin.OUT, value=0)
    assert chip.level(16) == 0


def test_machine_pwm_computes_div_top_and_compare_as_the_rp2_port():
    # 20 kHz: DIV 1, TOP = 125e6 / 20e3 - 1; 120 Hz needs a divider
    assert R.pwm_div_top(20_000) == (16, 6249)
    div16, top = R.pwm_div_top(120)
    assert div16 > 16 and top <= R.PWM_TOP_MAX
    assert abs(125e6 * 16 / (div16 * (top + 1)) - 120) < 0.01
    with pytest.raises(ValueError):
        R.pwm_div_top(1)


def test_resets_carry_what_the_chip_carries():
    chip, m, clock = _chip()
    m.mem32[R.WATCHDOG_SCRATCH0] = 0xC0FFEE
    m.Pin(18, m.Pin.OUT, value=1)
    pwm = m.PWM(m.Pin(20))
    pwm.freq(20_000)
    pwm.duty_u16(65535)
    clock.us = 100.0
    chip.reset("soft")  # the VM restarts: the slice stops (high: 100 % duty), the GPIO stays high
    assert chip.level(18) == 1 and chip.level(20) == 1 and not chip.slices[2].en
    assert m.reset_cause() == R.PWRON_RESET and m.mem32[R.WATCHDOG_SCRATCH0] == 0xC0FFEE
    chip.reset("watchdog")  # the chip resets: pads float (pulled low), scratch kept
    assert chip.level(18) == 0 and chip.level(20) == 0
    assert m.reset_cause() == R.WDT_RESET and m.mem32[R.WATCHDOG_SCRATCH0] == 0xC0FFEE
    assert m.ticks_us() == 0  # the timer restarted with the chip
    chip.reset("power")
    assert m.reset_cause() == R.PWRON_RESET and m.mem32[R.WATCHDOG_SCRATCH0] == 0


def test_adc_reads_the_temperature_sensor_and_a_wrong_reference():
    chip, m, clock = _chip()
    chip.chip_temp_c = 27.0
    assert R.temp_of_u16(m.ADC(4).read_u16()) == pytest.approx(27.0, abs=0.6)
    chip.chip_temp_c = 60.0
    assert R.temp_of_u16(m.ADC(m.ADC.CORE_TEMP).read_u16()) == pytest.approx(60.0, abs=0.6)
    chip.adc_inputs[28] = 40000
    assert abs(m.ADC(28).read_u16() - 40000) < 16  # 12 bits stretched to 16
    chip.adc_gain = 1.1
    assert abs(m.ADC(28).read_u16() - 44000) < 16


def test_a_timer_period_follows_the_rp2_float_rule():
    assert R.timer_delta_us(freq=1e6 / 80_000) == 80_000
    assert R.timer_delta_us(period=5) == 5000
    assert R.timer_delta_us(freq=2e6) == 1  # at least 1 us


def test_a_virtual_board_runs_across_the_ticks_wrap_and_resets():
    with VirtualBoard(start_us=(1 << 30) - 300_000) as board:
        board.set(0, 100.0, 300e-6)
        for k in range(1, 7):  # heartbeats keep the host watchdog quiet; the ticks wrap 0.3 s in
            board.until(0.1 * k)
            board.send(0x03)
        # (a pulse due at 0.6 s may have busy-waited the clock on by its width)
        assert 0 <= board.vm.ticks_us() - ((1 << 30) - 300_000 + 600_000 - (1 << 30)) <= 1_000
        n = board.pulse_count(0)
        starts = board.pulse_starts_us(0)
        assert n >= 58 and max(b - a for a, b in zip(starts, starts[1:])) < 10_500  # no gap at the wrap
        peak = board.peak_c(0)
        board.reset("soft")
        assert board.chip.level(board.fw.CHANNEL_PINS[0]) == 0
        board.until(0.7)
        assert board.pulse_count(0) == n  # main.py again: nothing runs until a host asks
        assert board.peak_c(0) >= peak - 1.0  # the same history, a little cooling
        board.reset("watchdog")
        assert board.ctl.channels[0].heat is not None and board.vm.reset_cause() == R.WDT_RESET
        assert [k for _, k in board.resets] == ["soft", "watchdog"]
        assert board.peak_c(0, air_c=20.0) < board.peak_c(0, air_c=30.0)


def test_a_hung_main_loop_is_reset_by_the_watchdog():
    with VirtualBoard() as board:
        board.until(0.05)
        # a callback that busy-waits past the watchdog's timeout (no main-loop pass feeds it)
        board.vm.Timer(mode=0, period=1, callback=lambda t: board.vm.sleep_us(150_000))
        board.until(0.3)
        assert [k for _, k in board.resets] == ["watchdog"]
