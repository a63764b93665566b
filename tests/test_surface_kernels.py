"""The pen window's compiled search (tactilize.surface._kernels) against its readable references.

Heights must be what ``SurfaceModel.regions`` (``scipy.ndimage.map_coordinates``)
gives, bumps what ``bumps_in`` (``scipy.signal.find_peaks``) finds: the same
indices and the same prominences, on random profiles and fields with plateaus,
edges, flat stretches, regions and extreme values.  And no compilation may land
on a pen batch.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tactilize.surface import surface_model
from tactilize.surface import _kernels
from tactilize.surface.bumps import bumps_in

SETTINGS = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# Few levels make plateaus and equal neighbours likely; extremes test the arithmetic's edges.
_LEVELS = st.sampled_from([0.0, 0.25, 0.5, 0.75, 1.0])
_EXTREME = st.sampled_from([1e300, -1e300, 1e-300, -1e-300, 5e-324, 1.7e308, -1.7e308, 0.0, -0.0])
_ANY = st.floats(allow_nan=False, allow_infinity=False, width=64)
_VALUE = st.one_of(_LEVELS, _LEVELS, _EXTREME, _ANY, st.floats(-1.0, 1.0))


def _kernel_bumps(h, ids, floors, a=0, b=None):
    b = len(h) if b is None else b
    oi, op = np.zeros(len(h) + 1, dtype=np.intp), np.zeros(len(h) + 1)
    n = _kernels.bumps_into(h, ids, floors, a, b, oi, op)
    return oi[:n], op[:n]


def _same(kernel, ref):
    (ki, kp), (ri, rp) = kernel, ref
    assert ki.tolist() == [int(i) for i in ri]
    assert np.array_equal(kp, np.asarray(rp, dtype=np.float64))  # to the bit, so within 1e-12


@st.composite
def profiles(draw):
    """A profile with runs of regions (-1 off every picture) and a floor per region."""
    n = draw(st.integers(0, 60))
    h = np.array(draw(st.lists(_VALUE, min_size=n, max_size=n)), dtype=np.float64)
    ids = np.zeros(n, dtype=np.intp)
    if n and draw(st.booleans()):
        cuts = sorted(draw(st.lists(st.integers(0, n), max_size=5)))
        region = 0
        for lo, hi in zip([0] + cuts, cuts + [n]):
            ids[lo:hi] = draw(st.sampled_from([-1, region, region + 1]))
            region += 1
    table = draw(st.lists(st.sampled_from([0.0, 0.02, 0.25, 1.0, 1e300]), min_size=8, max_size=8))
    floors = np.array([table[i % 8] for i in ids], dtype=np.float64)
    return h, ids, floors


@SETTINGS
@given(profiles())
@example((np.array([0.0, 1.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0]), np.zeros(8, np.intp), np.zeros(8)))
@example((np.array([1.0, 1.0, 1.0, 1.0]), np.zeros(4, np.intp), np.zeros(4)))
@example((np.array([0.0, 2.0, 2.0]), np.zeros(3, np.intp), np.zeros(3)))
@example((np.array([-1.7e308, 1.7e308, -1.7e308]), np.zeros(3, np.intp), np.zeros(3)))
def test_bumps_are_find_peaks_bumps(profile):
    h, ids, floors = profile
    _same(_kernel_bumps(h, ids, floors), bumps_in(h, ids, floors))


@SETTINGS
@given(profiles(), st.data())
def test_a_part_of_a_buffer_is_searched_as_that_part(profile, data):
    h, ids, floors = profile
    a = data.draw(st.integers(0, len(h)))
    b = data.draw(st.integers(a, len(h)))
    _same(_kernel_bumps(h, ids, floors, a, b), bumps_in(h[a:b], ids[a:b], floors[a:b]))


@st.composite
def fields_and_points(draw):
    rows, cols = draw(st.integers(1, 7)), draw(st.integers(1, 7))
    field = draw(arrays(np.float32, (rows, cols), elements=st.one_of(
        _LEVELS, st.floats(allow_nan=False, allow_infinity=False, width=32),
        st.sampled_from([3.4e38, -3.4e38, 1e-45]))))
    pitch = draw(st.sampled_from([1e-4, 0.25e-3, 1.0 / 3.0 * 1e-3]))
    # Points on, around and exactly at the edges and pixel centres.
    coord = st.one_of(st.floats(-2.0, 9.0), st.integers(-1, 8).map(float), st.integers(-2, 18).map(lambda k: k / 2))
    n = draw(st.integers(1, 40))
    px = np.array(draw(st.lists(coord, min_size=n, max_size=n)))
    py = np.array(draw(st.lists(coord, min_size=n, max_size=n)))
    return field.astype(np.float64), pitch, px * pitch, py * pitch


def _kernel_heights(sm, x, y):
    n = len(x)
    h, ids, fl = np.zeros(n), np.zeros(n, dtype=np.intp), np.zeros(n)
    _kernels.heights_into(sm._padded, sm._inv_pitch[0], sm._inv_pitch[1], sm.prominence_floor, x, y, 0, n, h, ids, fl)
    return h, ids, fl


@SETTINGS
@given(fields_and_points())
def test_heights_are_map_coordinates_heights(case):
    field, pitch, x, y = case
    # tip_radius tiny: the model keeps the field as given (no filter), so extremes survive.
    with np.errstate(all="ignore"):  # the floor's deviation of extreme heights overflows; not tested here
        sm = surface_model(field, pitch_m=pitch, tip_radius_m=1e-9)
    kh, kid, kfl = _kernel_heights(sm, x, y)
    rh, rid, rfl = sm.regions(x, y)
    assert np.array_equal(kh, rh, equal_nan=True)
    assert np.allclose(kh, rh, rtol=0, atol=1e-12, equal_nan=True)
    assert kid.tolist() == rid.tolist() and np.array_equal(kfl, rfl)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 2 * math.pi), st.integers(0, 40), st.integers(0, 30))
def test_one_pass_search_is_regions_then_bumps_in(seed, angle, kept, npred):
    """search_window = the prediction, SurfaceModel.regions and bumps_in, on a field with flat patches."""
    rng = np.random.default_rng(seed)
    field = np.round(rng.random((12, 16)) * 4) / 4  # plateaus
    sm = surface_model(field, pitch_m=0.5e-3, tip_radius_m=1e-9)
    n = kept + npred + 2
    t, x, y = np.zeros(n), np.zeros(n), np.zeros(n)
    x[:kept] = rng.uniform(-1e-3, 9e-3, kept)
    y[:kept] = rng.uniform(-1e-3, 7e-3, kept)
    h, ids, fl = np.zeros(n), np.zeros(n, dtype=np.intp), np.zeros(n)
    oi, op, ot = np.zeros(n, dtype=np.intp), np.zeros(n), np.zeros(n)
    lo = int(rng.integers(0, kept + 1))
    h[:lo], ids[:lo], fl[:lo] = sm.regions(x[:lo], y[:lo])
    step, s0, t0, x0, y0, speed = 0.1e-3, 0.537e-3, 2.0, 4e-3, 3e-3, 0.04
    k1 = math.floor(s0 / step) + 1
    ux, uy = math.cos(angle), -math.sin(angle)
    a = int(rng.integers(0, kept + 1))
    count = _kernels.search_window(sm._padded, sm._inv_pitch[0], sm._inv_pitch[1], sm.prominence_floor, t, x, y, h,
                                   ids, fl, lo, kept, npred, k1, step, t0, x0, y0, s0, ux, uy, speed, a, oi, op, ot)
    off = np.arange(k1, k1 + npred) * step - s0
    assert np.array_equal(x[kept : kept + npred], x0 + ux * off)
    assert np.array_equal(t[kept : kept + npred], t0 + off / speed)
    rh, rid, rfl = sm.regions(x[: kept + npred], y[: kept + npred])
    assert np.array_equal(h[: kept + npred], rh, equal_nan=True) and ids[: kept + npred].tolist() == rid.tolist()
    _same((oi[:count], op[:count]), bumps_in(rh[a:], rid[a:], rfl[a:]))
    assert np.array_equal(ot[:count], t[a + oi[:count]])


_FRESH = """
import json
from tactilize.pen.samples import PenSample
from tactilize.surface import CompositeSurface, SurfaceStroke, surface_model, _kernels, _stroke_kernels
from tactilize.surface.fields import grain_field

def signatures():
    got = {k: len(getattr(_kernels, k).signatures) for k in ("search_window", "predict_into", "bumps_into")}
    for k in ("place_crossings", "fire_due", "window_stats"):
        got[k] = len(getattr(_stroke_kernels, k).signatures)
    return got

f = grain_field(1.2e-3, (30e-3, 10e-3), seed=3)
sm = surface_model(f.heights, pitch_m=f.pitch_m)
before = signatures()
strokes = [SurfaceStroke(sm), SurfaceStroke(CompositeSurface.of([sm, sm], cols=2))]
ready = signatures()
fired = 0
for stroke in strokes:
    for k in range(200):
        t = 0.004 * k
        stroke.update([PenSample(t, 2e-3 + 0.04 * t, 5e-3)], 0.04, 0.0)
        stroke.window_statistics(0.15)
        fired += stroke.newly_fired
# An API caller's integer times and positions (whole seconds, metres) compile nothing new either.
whole = SurfaceStroke(sm)
for k in range(3):
    whole.update([PenSample(k, 0, 0)], 0.0, None)
print(json.dumps({"before": before, "ready": ready, "after": signatures(), "fired": fired}))
"""


def test_no_compilation_lands_on_a_pen_batch():
    """In a fresh process, making the stroke (a session's picture) readies every kernel the pen
    path calls; its batches then find them ready (numba compiles a new type on first call)."""
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _FRESH], capture_output=True, text=True, check=True).stdout
    got = json.loads(out.strip().splitlines()[-1])
    assert all(v == 0 for v in got["before"].values())  # nothing loaded before
    assert all(v >= 1 for v in got["ready"].values())
    assert got["fired"] > 20  # the search did run and find bumps
    assert got["after"] == got["ready"]


_SERVER = """
import json
from tactilize.actuators.simulated import SimulatedOutput
from tactilize.mapping import Profile
from tactilize.surface import _kernels, _stroke_kernels
from tactilize.web.state import ServerState

names = {_kernels: ("search_window", "predict_into", "bumps_into"),
         _stroke_kernels: ("place_crossings", "fire_due", "window_stats")}
count = lambda: {k: len(getattr(m, k).signatures) for m, ks in names.items() for k in ks}
before = count()
ServerState(SimulatedOutput(start=False), Profile.preset("surface")).warm()
print(json.dumps({"before": before, "after": count()}))
"""


def test_a_server_readies_every_kernel_of_the_pen_path_when_it_starts():
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _SERVER], capture_output=True, text=True, check=True).stdout
    got = json.loads(out.strip().splitlines()[-1])
    assert all(v == 0 for v in got["before"].values())
    assert all(v >= 1 for v in got["after"].values()), got["after"]
