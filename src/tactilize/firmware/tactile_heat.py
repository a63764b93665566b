# The board's running heat estimate of each wire (MicroPython module, copied to
# the board next to main.py; see docs/firmware.md).
#
# A per-frame check bounds a train in its periodic state, but not the way into
# it: a big pulse right after a hot train lands on a hot wire.  So the board
# keeps, per wire, the lumped heat balance of the host's wire model without its
# latent heat (docs/references.md, section 8 (board heat estimate)):
#
#     C d(rise)/dt = P_cont - h A rise,      rise += E / C at each pulse,
#
# with rise the wire's temperature above the hottest design air [K], P_cont the
# standby bias and any PWM train as a mean heat [W], and E the heat of each
# timed pulse [J] at the bound on the heat while on.  Every pulse is admitted
# only while rise + E / C stays within the budget the stored config allows.
# The latent heat cannot raise a peak above it: once the wire passes A_f all the
# heat its cooling gave back has been absorbed again, and below A_f it is under
# every budget's top (the same reference).
#
# Units: SI floats (K, J, W, s) and the board's microsecond ticks.
# MicroPython-compatible code only.

import math

try:
    import tactile_wire as W
except ImportError:  # on the host, inside the package
    from tactilize.firmware import tactile_wire as W

# The RP2040's own temperature sensor (ADC input 4) and its line: V = 0.706 V at
# 27 C, -1.721 mV/K (docs/references.md, section 10 (ADC)).
TEMP_ADC = 4
TEMP_V27 = 0.706
TEMP_SLOPE_V_K = 0.001721
# Readings outside this range [C] are not a temperature: they tighten nothing.
TEMP_PLAUSIBLE_C = (-40.0, 125.0)


class Air:
    """The air around the board's wires: the design air the stored config was
    made for (``design_air_c``), or warmer when the chip's own sensor (``adc``,
    None: none) reads warmer.  The die runs at or above the air around it, so a
    reading may only lower the budget, never raise it."""

    def __init__(self, cfg, adc):
        self.design_c = cfg["design_air_c"]
        self.budget_design_k = cfg["budget_k"]
        self.adc = adc
        self.chip_c = None
        self.air_c = self.design_c

    def budget_k(self):
        """Read the sensor (4 readings); the budget [K] for the air it shows."""
        air = self.design_c
        if self.adc is not None:
            v = 0.0
            for _ in range(4):
                v += self.adc.read_u16() * W.ADC_FULL_SCALE_V / 65535.0
            chip = 27.0 - (v / 4 - TEMP_V27) / TEMP_SLOPE_V_K
            if TEMP_PLAUSIBLE_C[0] <= chip <= TEMP_PLAUSIBLE_C[1]:
                self.chip_c = chip
                if chip > air:
                    air = chip
        self.air_c = air
        budget = self.budget_design_k - (air - self.design_c)
        return budget if budget > 0 else 0.0


class HeatEstimate:
    """One wire's temperature rise above the hottest design air [K], from the
    heat the board gave it (``cfg``: conductance_w_k, heat_capacity_j_k,
    budget_k as in tactile_wire.DEFAULT_CONFIG).  ``ticks_diff(a, b)`` is the
    board's tick difference [us].  It starts at the budget: after any reset or
    power-up the board cannot know how long it was off, so the wire may still be
    as hot as the board ever let it be, and it cools in the estimate before full
    energy is admitted (about 2 s: a few time constants C / (h A)).  ``hot=False``
    is for the host's simulations of a board that has been idle that long."""

    def __init__(self, cfg, ticks_diff, hot=True):
        self.hA = cfg["conductance_w_k"]
        self.c = cfg["heat_capacity_j_k"]
        self.budget = cfg["budget_k"]
        self.tau_us = self.c / self.hA * 1e6
        self.diff = ticks_diff
        self.rise_k = self.budget if hot else 0.0
        self.power_w = 0.0
        self.at_us = None

    def assume_hot(self):
        """The wire may be at the budget (after a fault nothing below it is known)."""
        if self.rise_k < self.budget:
            self.rise_k = self.budget

    def set_budget(self, budget_k):
        """A new budget [K] (the room turned out warmer than the design air)."""
        self.budget = budget_k

    def advance(self, now_us):
        """Bring the estimate to ``now_us`` under the continuous heat."""
        if self.at_us is None:
            self.at_us = now_us
            return
        dt = self.diff(now_us, self.at_us)
        if dt <= 0:
            return
        self.at_us = now_us
        ss = self.power_w / self.hA
        self.rise_k = ss + (self.rise_k - ss) * math.exp(-dt / self.tau_us)

    def set_power(self, now_us, power_w):
        """The continuous heat [W] from ``now_us`` on (bias, PWM trains as their mean)."""
        self.advance(now_us)
        self.power_w = power_w

    def room_j(self, now_us):
        """The most heat [J] one pulse may add at ``now_us``."""
        self.advance(now_us)
        room = (self.budget - self.rise_k) * self.c
        return room if room > 0 else 0.0

    def add(self, now_us, energy_j):
        """A pulse of ``energy_j`` [J] starting at ``now_us``."""
        self.advance(now_us)
        self.rise_k += energy_j / self.c
