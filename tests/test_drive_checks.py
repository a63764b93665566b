"""Drive's quick check of plain floats accepts and refuses exactly what check_finite does."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactilize.drive import Drive
from tactilize.errors import DriveError, check_finite

# Values at and around each bound, of every type a caller passes.
_edge = st.sampled_from([0.0, -0.0, 1.0, 1.0 + 1e-12, -1e-300, 5e-324, math.inf, -math.inf, math.nan, 300.0])
_number = st.one_of(
    _edge,
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-0.5, 1.5),
    st.integers(-2, 3),
    st.booleans(),
    st.floats(-0.5, 1.5).map(np.float64),
)


def _accepted_by_reference(f, w, a, s, r) -> bool:
    try:
        for v in (f, w):
            check_finite(v, "<drive>", error=DriveError, minimum=0.0)
        check_finite(a, "<drive>", error=DriveError, minimum=0.0, maximum=1.0)
        for v in (s, r):
            if v is not None:
                check_finite(v, "<drive>", error=DriveError, minimum=0.0, maximum=1.0)
    except DriveError:
        return False
    return True


@settings(max_examples=400, deadline=None)
@given(_number, _number, _number, st.one_of(st.none(), _number), st.one_of(st.none(), _number))
def test_drive_accepts_what_check_finite_accepts(f, w, a, s, r):
    ok = _accepted_by_reference(f, w, a, s, r)
    if ok:
        d = Drive(f, w, a, ["x"], s, r)
        assert d.clamped == ("x",)
        assert d.replace(pulse_width_s=0.5).pulse_width_s == 0.5
    else:
        with pytest.raises(DriveError):
            Drive(f, w, a, (), s, r)


def test_replace_checks_and_refuses_unknown_fields():
    d = Drive(100.0, 1e-3, 1.0, ("a",), 0.5, 0.9)
    assert d.replace(strength=None) == Drive(100.0, 1e-3, 1.0, ("a",), None, 0.9)
    with pytest.raises(DriveError):
        d.replace(pulse_width_s=math.nan)
    with pytest.raises(DriveError):
        d.replace(amplitude=1.5)
    with pytest.raises(TypeError):
        d.replace(width=1.0)
