# The wire on the board: energy limits, self-sensing, and the hold between host messages.
#
# MicroPython module, copied to the board next to main.py (docs/hardware.md).  It
# knows the wire and the circuit only as a few numbers stored on the board's
# flash (tactile_cfg.txt, written in maintenance mode; never over the protocol),
# with the defaults below for the paper's 75 um wire on the aa-resistor circuit.
# tactilize.boardhost.board writes those numbers from the host's wire model, and
# tests/test_firmware_safety.py checks that they equal it.
#
# Units: SI floats (W, J, K, s, ohm, A, V).  MicroPython-compatible code only.

# ---------------------------------------------------------------- the wire and the circuit
# The same quantities as the host's SafetyEnvelope (tactilize.actuators.sma.envelope):
# conductance h A_s [W/K], heat capacity C [J/K], the temperature budget [K]
# (margin x (T_max - hottest design air)), the most the switched-on circuit can
# put into the wire at any of its resistances [W], and the resistance range [ohm].
DEFAULT_CONFIG = {
    "conductance_w_k": 0.00013430308594096363,
    "heat_capacity_j_k": 7.155151528768257e-05,
    "budget_k": 57.0,
    "max_power_w": 0.15750929066017705,
    "r_martensite_ohm": 0.5432488724203361,
    "r_austenite_ohm": 0.6790610905254202,
    "current_min_a": 0.481613513883029,
    "current_spread": 1.0,
    # The hottest air the budget was made for [C]; a warmer room needs a config
    # made for it, and the chip's own sensor lowers the budget when it reads
    # warmer (controller.py).
    "design_air_c": 30.0,
}
CONFIG_FILE = "tactile_cfg.txt"
CAL_FILE = "tactile_cal.txt"

# ---------------------------------------------------------------- the sense path (docs/hardware.md)
# Per channel: a 0.1 ohm sense resistor in the MOSFET's source lead into a
# current-sense amplifier of gain 50 (0.5 A -> 2.5 V) on ADC0 / ADC1; the wire's
# supply rail, after the polyfuse, through a 10k/10k divider on ADC2.
ADC_FULL_SCALE_V = 3.3
SENSE_OHM = 0.1
SENSE_GAIN = 50.0
RAIL_DIVIDER = 2.0
# Calibration per channel, stored on the board in CAL_FILE (written with mpremote
# in maintenance mode, like CONFIG_FILE; see docs/hardware.md): amperes per ADC
# count (read_u16 scale) and the resistance in series with the wire between the
# rail's tap and ground (series resistor, switch, sense resistor) [ohm].
DEFAULT_AMPS_PER_COUNT = ADC_FULL_SCALE_V / 65535.0 / (SENSE_GAIN * SENSE_OHM)
DEFAULT_PATH_OHM = (5.1 + 0.05 + 0.1, 5.1 + 0.05 + 0.1)  # aa-resistor: 5.1 ohm, switch, sense
RAIL_VOLTS_PER_COUNT = ADC_FULL_SCALE_V / 65535.0 * RAIL_DIVIDER
# A reading counts as "during a pulse" above this current [A]; fewer are noise.
MIN_SENSE_A = 0.05
# Readings averaged into one measurement.
SENSE_AVERAGE = 16
# A measurement older than this [ms] no longer describes the wire.
SENSE_FRESH_MS = 1000
# What the limits allow for the calibration's own error (it is measured on the
# bench and written to CAL_FILE in maintenance mode; no host can change it).
CAL_TOLERANCE = 0.01
# A sense reading at or above this read_u16 count is clipped: the amplifier
# saturated (more current than the path was designed for); it bounds nothing.
ADC_CLIPPED = 65000
# A sense fault (docs/references.md, section 8 (sense faults)): a measured
# resistance outside FAULT_R_LOW x the wire's lower .. FAULT_R_HIGH x its higher
# phase resistance, or a current more than FAULT_CURRENT off what the rail can
# drive through the path and the wire; a calibration outside CAL_RANGE x the
# documented sense path, or a path outside 0 .. CAL_PATH_MAX_OHM.  A faulty
# path bounds nothing: the limits fall back to the circuit's worst case.
FAULT_R_LOW = 0.8
FAULT_R_HIGH = 1.2
FAULT_CURRENT = 0.2
CAL_RANGE = (0.8, 1.25)
CAL_PATH_MAX_OHM = 20.0

# ---------------------------------------------------------------- the hold (between host messages)
# The host's controller decides the heat (tactilize.actuators.sma.controller);
# the board keeps it while the cells sag: the pulse width is the host's pulse
# energy over the heat the circuit delivers now (I^2 R, measured), and the bias is
# the host's bias power over it, trimmed by an integral on the resistance so the
# wire stays at the host's target between messages.
HOLD_TRIM_PER_S = 2.0  # bias trim rate [1/s per unit of normalised resistance error]
HOLD_TRIM_MAX = 0.5  # the trim may add or take at most 50 % of the host's holding heat


def parse_config(text, defaults):
    """key value lines (# comments) over a copy of defaults; unknown keys are ignored."""
    out = dict(defaults)
    for line in text.split("\n"):
        line = line.split("#")[0].strip()
        if not line:
            continue
        parts = line.split()
        if len(parts) == 2 and parts[0] in out:
            try:
                value = float(parts[1])
            except ValueError:
                continue
            # A stored number can only make the board stricter than a sane floor.
            if value == value and value > 0 and value != float("inf"):
                out[parts[0]] = value
    return out


def load_calibration(text, channels):
    """Per-channel (amperes per count, path [ohm]) from CAL_FILE's text."""
    d = {}
    for i in range(channels):
        d["amps_per_count_%d" % i] = DEFAULT_AMPS_PER_COUNT
        d["path_ohm_%d" % i] = DEFAULT_PATH_OHM[i] if i < len(DEFAULT_PATH_OHM) else DEFAULT_PATH_OHM[0]
    d = parse_config(text, d)
    return [(d["amps_per_count_%d" % i], d["path_ohm_%d" % i]) for i in range(channels)]


def calibration_fault(amps_per_count, path_ohm):
    """True when a channel's stored calibration is outside its plausible range."""
    k = amps_per_count / DEFAULT_AMPS_PER_COUNT
    return not (CAL_RANGE[0] <= k <= CAL_RANGE[1]) or not (0.0 <= path_ohm <= CAL_PATH_MAX_OHM)


def calibration_text(cal):
    out = []
    for i in range(len(cal)):
        out.append("amps_per_count_%d %r" % (i, cal[i][0]))
        out.append("path_ohm_%d %r" % (i, cal[i][1]))
    return "\n".join(out) + "\n"


def read_text(path):
    try:
        with open(path) as fh:
            return fh.read()
    except OSError:
        return ""


class WireLimits:
    """The energy limits: the SafetyEnvelope's bounds, evaluated on the board.

    Peak <= hottest air + (f E + b P) / (h A) + E / C, with E = w P the heat of
    one pulse and P the configured circuit's worst case P_max, the most heat
    the switched-on circuit can put into the wire.  A measurement never lowers
    P: a sensing error common to the current and the rail (a wrong ADC
    reference reads both k times the truth) passes every plausibility check and
    would loosen the limit by 1 / k^2.  Readings may only tighten: one that
    implies more than the circuit can give is a sense fault (Sense), and the
    budget shrinks when the chip reads a warmer room (controller.py)."""

    def __init__(self, cfg):
        self.h = cfg["conductance_w_k"]
        self.c = cfg["heat_capacity_j_k"]
        self.budget = cfg["budget_k"]
        self.p_max = cfg["max_power_w"]
        self.i_min = cfg["current_min_a"]
        self.spread = cfg["current_spread"]

    def power(self, current_a=0.0):
        """Bound on the heat while on [W]: the circuit's worst case, whatever
        ``current_a`` [A] was measured (see the class)."""
        return self.p_max

    def rise_k(self, f_hz, width_s, bias, p_w, j=0.0):
        """The bound on the rise [K]; a train jittered by j periods may bring
        its pulses j periods closer than even ones, which adds at most j E / C
        (docs/references.md, section 2 (jittered trains))."""
        e = width_s * p_w
        return (f_hz * e + bias * p_w) / self.h + (1.0 + j) * e / self.c

    def allowed(self, f_hz, width_s, bias, p_w, j=0.0):
        return self.rise_k(f_hz, width_s, bias, p_w, j) <= self.budget * (1 + 1e-9)

    def heat_allowed(self, f_hz, pulse_j, bias_w):
        """The same bound for heat given directly: per pulse [J] and bias [W]."""
        return (f_hz * pulse_j + bias_w) / self.h + pulse_j / self.c <= self.budget * (1 + 1e-9)

    def max_width_s(self, f_hz, bias, p_w, j=0.0):
        room = self.budget - bias * p_w / self.h
        if room <= 0 or f_hz <= 0:
            return 0.0
        return room / (f_hz / self.h + (1.0 + j) / self.c) / p_w

    def max_bias(self, f_hz, width_s, p_w, j=0.0):
        e = width_s * p_w
        room = self.budget - (1.0 + j) * e / self.c
        if room <= 0:
            return 0.0
        b = (room * self.h - f_hz * e) / p_w
        return 0.0 if b < 0 else (1.0 if b > 1 else b)


class Sense:
    """Self-sensing of one channel: ADC readings taken while current flows ->
    the wire's resistance and current (averaged over SENSE_AVERAGE readings),
    each measurement checked against the wire and circuit in ``cfg`` (fault)."""

    def __init__(self, adc_i, adc_rail, amps_per_count, path_ohm, cfg=None):
        cfg = DEFAULT_CONFIG if cfg is None else cfg
        r = (cfg["r_martensite_ohm"], cfg["r_austenite_ohm"])
        self.r_lo, self.r_hi = min(r), max(r)
        # A current sink regulates below what the rail could drive: only a voltage
        # circuit (spread 1) must carry the rail's current.
        self.voltage_circuit = cfg["current_spread"] <= 1.0
        # The calibration is checked once: a bad one is a fault for good.
        self.cal_fault = calibration_fault(amps_per_count, path_ohm)
        self.fault = self.cal_fault
        self.adc_i = adc_i
        self.adc_rail = adc_rail
        self.amps_per_count = amps_per_count
        self.path_ohm = path_ohm
        self.sum_i = 0.0
        self.sum_v = 0.0
        self.n = 0
        self.resistance_ohm = 0.0
        self.current_a = 0.0
        self.rail_v = 0.0
        self.measured_ms = None
        self.count = 0

    def sample(self, now_ms):
        """One reading; returns True when it completed a measurement."""
        raw = self.adc_i.read_u16()
        if raw >= ADC_CLIPPED:
            self.measured_ms = None  # no bound from a clipped reading
            self.n = 0
            self.sum_i = self.sum_v = 0.0
            return False
        i = raw * self.amps_per_count
        if i < MIN_SENSE_A:
            return False
        v = self.adc_rail.read_u16() * RAIL_VOLTS_PER_COUNT
        self.sum_i += i
        self.sum_v += v
        self.n += 1
        if self.n < SENSE_AVERAGE:
            return False
        i = self.sum_i / self.n
        v = self.sum_v / self.n
        self.sum_i = self.sum_v = 0.0
        self.n = 0
        r = v / i - self.path_ohm
        self.fault = self.cal_fault or self._faulty(r, i, v)
        if r <= 0:
            return False
        self.resistance_ohm = r
        self.current_a = i
        self.rail_v = v
        self.measured_ms = now_ms
        self.count = (self.count + 1) & 0xFFFF
        return True

    def _faulty(self, r, i, v):
        if not (FAULT_R_LOW * self.r_lo <= r <= FAULT_R_HIGH * self.r_hi):
            return True
        if i > (1.0 + FAULT_CURRENT) * v / (self.path_ohm + self.r_lo):
            return True
        return self.voltage_circuit and i < (1.0 - FAULT_CURRENT) * v / (self.path_ohm + self.r_hi)

    def fresh(self, now_ms, ticks_diff):
        return not self.fault and self.measured_ms is not None and ticks_diff(now_ms, self.measured_ms) <= SENSE_FRESH_MS

    def power_w(self, now_ms, ticks_diff):
        """I^2 R of the latest fresh measurement [W], 0 when none."""
        if not self.fresh(now_ms, ticks_diff):
            return 0.0
        return self.current_a * self.current_a * self.resistance_ohm

    def current_bound_a(self, now_ms, ticks_diff):
        """The latest fresh current [A] for WireLimits.power, 0 when none."""
        return self.current_a if self.fresh(now_ms, ticks_diff) else 0.0


class Hold:
    """Keeps the host's planned heat between host messages (see HOLD_TRIM_*).

    The host gives, per channel: the pulse frequency [Hz], the heat per pulse [J],
    the bias heat [W] and the resistance [ohm] it wants the wire at; step()
    turns them into a pulse width [s] and a bias level [0, 1] at the measured
    heat while on [W], within the WireLimits of the measured current [A]."""

    def __init__(self, limits, cfg):
        self.limits = limits
        self.r_span = cfg["r_martensite_ohm"] - cfg["r_austenite_ohm"]
        self.clear()

    def clear(self):
        self.frequency_hz = 0.0
        self.energy_j = 0.0
        self.bias_w = 0.0
        self.target_ohm = 0.0
        self.trim = 0.0

    @property
    def active(self):
        return self.target_ohm > 0 or self.energy_j > 0 or self.bias_w > 0

    def set(self, frequency_hz, energy_j, bias_w, target_ohm):
        self.frequency_hz = frequency_hz
        self.energy_j = energy_j
        self.bias_w = bias_w
        self.target_ohm = target_ohm
        self.trim = 0.0

    def step(self, resistance_ohm, power_w, dt_s, width_now_s=0.0, current_a=0.0):
        """(pulse width [s], bias level) for the next interval; power_w is the
        measured heat while on [W] (0: none yet; the width is then 0: keep the host's)."""
        measured = power_w > 0
        if not measured:
            # Nothing measured yet: the bias with the circuit's worst case (the
            # smallest level; it gives the first readings), the host's width kept.
            power_w = self.limits.p_max
        if self.target_ohm > 0 and resistance_ohm > 0 and self.r_span != 0:
            # err > 0: more martensite than meant (the wire is cooler): more heat.
            # (r_span = R_martensite - R_austenite carries the wire's sign.)
            err = (resistance_ohm - self.target_ohm) / self.r_span
            self.trim += HOLD_TRIM_PER_S * err * dt_s
            if self.trim > HOLD_TRIM_MAX:
                self.trim = HOLD_TRIM_MAX
            elif self.trim < -HOLD_TRIM_MAX:
                self.trim = -HOLD_TRIM_MAX
        p_bound = self.limits.power(current_a if measured else 0.0)
        f = self.frequency_hz
        width = 0.0
        if f > 0 and self.energy_j > 0 and measured:
            width = self.energy_j / power_w
            w_max = self.limits.max_width_s(f, 0.0, p_bound)
            if width > w_max:
                width = w_max
            if width > 0.5 / f:
                width = 0.5 / f
        hold_w = self.bias_w + f * self.energy_j
        bias = (self.bias_w + self.trim * hold_w) / power_w
        b_max = self.limits.max_bias(f, width if width > 0 else width_now_s, p_bound)
        if bias > b_max:
            bias = b_max
        if bias < 0:
            bias = 0.0
        return width, bias


# ------------------------------------------------------------ irregular textures
# As tactilize.synthesis on the host: pulse k of an irregular train starts at
# (k + j u_k) periods, u_k uniform in [-1/2, 1/2), j = JITTER_MAX_PERIODS (1 -
# regularity), capped so neighbours never touch.  The board draws u_k from its own
# seeded generator (xorshift32): the same statistics, not the host's table.
JITTER_MAX_PERIODS = 0.6
REGULARITY_EVEN = 65535


def jitter_depth(regularity_q16, period_us, width_us):
    """Depth j of the pulse-position jitter [periods]; 0 for an even train."""
    if regularity_q16 >= REGULARITY_EVEN or period_us <= 0:
        return 0.0
    j = JITTER_MAX_PERIODS * (REGULARITY_EVEN - regularity_q16) / REGULARITY_EVEN
    room = 1.0 - (width_us + 1) / period_us
    return max(0.0, min(j, room))


class Jitter:
    """A seeded uniform generator in [-1/2, 1/2) (xorshift32)."""

    def __init__(self, seed=0x2545F491):
        self.state = (seed & 0xFFFFFFFF) or 1

    def next(self):
        x = self.state
        x ^= (x << 13) & 0xFFFFFFFF
        x ^= x >> 17
        x ^= (x << 5) & 0xFFFFFFFF
        self.state = x
        return x / 4294967296.0 - 0.5
