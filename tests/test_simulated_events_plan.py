"""The plan of the operating point while the simulated wire plays events.

Every pulse is planned when it plays; the plan of the window's equivalent drive is what
``play`` reports (the page shows it; an export records it as the wire's drive).
Stepped by ``advance`` (offline: a stroke run for an export) each call gets its own plan.
Running in real time (the pen server) the simulation thread makes it when it takes the
events, so a pen batch does not plan it again: a batch gets the newest plan, the first
batch after a steady drive, a lift or a stop its own.  The tests below step that mode by
hand (the output's event player's ``plan_on_take``, which ``start`` sets) so the thread's
moments are the test's; they count the controllers' plans to see who planned.
"""

from __future__ import annotations

import threading
import time

from tactilize.actuators.simulated import SimulatedOutput
from tactilize.drive import Drive
from tactilize.surface.events import PulseEvent
from tactilize.surface.rendering import Frame


def _eq(rate_hz: float, strength: float = 0.6) -> Drive:
    return Drive(rate_hz, 3e-4, 1.0, (), strength, 0.8)


def _events(now_s: float) -> list[PulseEvent]:
    return [PulseEvent(now_s + 0.005, 0.6), PulseEvent(now_s + 0.015, 0.7)]


def _counting(out: SimulatedOutput) -> list[int]:
    calls = [0]
    for ctrl in out.controllers:
        plan = ctrl.plan

        def counted(d, _plan=plan):
            calls[0] += 1
            return _plan(d)

        ctrl.plan = counted  # type: ignore[method-assign]
    return calls


def _assert_planned(out: SimulatedOutput, shown: Drive, d: Drive) -> None:
    """``shown`` is the controller's plan of ``d`` at the wire's state now."""
    want = out.controllers[0].plan(d)
    assert shown.pulse_frequency_hz == d.pulse_frequency_hz
    assert shown.pulse_width_s == want.pulse_width_s and shown.amplitude == want.level


def _live() -> SimulatedOutput:
    """The real-time mode, stepped by hand."""
    out = SimulatedOutput(start=False)
    out.event_player.plan_on_take = True
    return out


def test_offline_every_hand_over_gets_the_plan_of_its_own_operating_point():
    """A stroke run offline (an export's wire column): no lag, whatever the steps."""
    out = SimulatedOutput(start=False)
    for k in range(6):
        d = _eq(60.0 + 10 * k)
        shown = out.play(Frame(tuple(_events(1.0 + 0.004 * k)), d, False), 1.0 + 0.004 * k, [d, d])
        _assert_planned(out, shown[0], d)
        if k % 2:
            out.advance(0.004)


def test_in_real_time_the_pen_thread_plans_once_and_the_wire_thread_the_rest():
    out = SimulatedOutput()  # its thread running
    try:
        by_thread: dict[str, int] = {}
        for ctrl in out.controllers:
            plan = ctrl.plan

            def counted(d, _plan=plan):
                name = threading.current_thread().name
                by_thread[name] = by_thread.get(name, 0) + 1
                return _plan(d)

            ctrl.plan = counted  # type: ignore[method-assign]
        me = threading.current_thread().name
        for k in range(20):
            d = _eq(60.0 + 5 * k)
            out.play(Frame(tuple(_events(1.0 + 0.004 * k)), d, False), 1.0 + 0.004 * k, [d, d])
        assert by_thread.get(me) == 1  # the first hand-over only
        last = _eq(60.0 + 5 * 19)
        # The wire's thread takes the newest events within a tick and plans their operating point.
        def shown_hz() -> float | None:
            shown = out.event_player.shown
            return shown[0].pulse_frequency_hz if shown else None

        deadline = time.monotonic() + 10.0  # a generous wait, not a timing assertion
        while time.monotonic() < deadline and shown_hz() != last.pulse_frequency_hz:
            time.sleep(0.01)
        assert shown_hz() == last.pulse_frequency_hz
        assert sum(v for k, v in by_thread.items() if k != me) >= 1
        assert by_thread.get(me) == 1
    finally:
        out.close()


def test_batches_get_the_plan_the_wire_made_and_do_not_plan_it_again():
    out = _live()
    calls = _counting(out)
    first = _eq(60.0)
    shown = out.play(Frame(tuple(_events(1.0)), first, False), 1.0, [first, first])
    assert calls[0] == 1  # the first hand-over plans its own (both pins share one plan)
    assert shown[0].pulse_frequency_hz == 60.0
    for k in range(1, 6):  # new operating points, no simulation step in between
        d = _eq(60.0 + 10 * k)
        again = out.play(Frame(tuple(_events(1.0 + 0.004 * k)), d, False), 1.0 + 0.004 * k, [d, d])
        assert again is shown
    assert calls[0] == 1
    out.advance(0.004)  # the wire takes the newest events and plans their operating point
    assert calls[0] == 2
    later = _eq(130.0)
    newest = out.play(Frame(tuple(_events(1.03)), later, False), 1.03, [later, later])
    assert newest is not shown
    # The plan of the operating point the wire took: the last handed over before the step (110 Hz).
    _assert_planned(out, newest[0], _eq(110.0))
    assert calls[0] == 3  # (the line above planned once itself)


def test_after_a_steady_drive_or_a_stop_the_next_events_are_planned_afresh():
    out = _live()
    a = _eq(50.0)
    out.play(Frame(tuple(_events(1.0)), a, False), 1.0, [a, a])
    out.advance(0.004)
    out.apply([_eq(200.0, 0.3)] * 2)
    b = _eq(150.0)
    shown = out.play(Frame(tuple(_events(1.1)), b, False), 1.1, [b, b])
    assert shown[0].pulse_frequency_hz == 150.0  # not the 50 Hz plan from before the steady drive
    out.advance(0.004)
    out.stop()
    c = _eq(90.0)
    assert out.play(Frame(tuple(_events(1.2)), c, False), 1.2, [c, c])[0].pulse_frequency_hz == 90.0


def test_a_plan_the_wire_made_before_a_stop_is_not_shown_after_it():
    """The stop lands between the wire taking events and storing their plan: the plan is dropped."""
    out = _live()
    a = _eq(50.0)
    out.play(Frame(tuple(_events(1.0)), a, False), 1.0, [a, a])
    b = _eq(70.0)
    out.play(Frame(tuple(_events(1.004)), b, False), 1.004, [b, b])
    ctrl = out.controllers[0]
    plan = ctrl.plan

    def stop_meanwhile(d):
        out.stop()  # the pen lifts while the wire plans
        return plan(d)

    ctrl.plan = stop_meanwhile  # type: ignore[method-assign]
    out.advance(0.004)
    ctrl.plan = plan  # type: ignore[method-assign]
    c = _eq(120.0)
    assert out.play(Frame(tuple(_events(1.3)), c, False), 1.3, [c, c])[0].pulse_frequency_hz == 120.0
