"""The surface model as a compact file a web page reads: quantised tip-filtered heights and the rule's parameters.

A shop page renders the ``surface`` rendering in the browser (docs/shop.md), so it
needs what :class:`~tactilize.surface.model.SurfaceModel` holds, small enough to load
with a product page: the tip-filtered heights at the model's resolution, 8 bits each,
their real-world scale, and every parameter of the rule the page runs
(``site/static/surface-rule.js``).  Python writes the parameters from the constants
of :mod:`tactilize.surface` and :mod:`tactilize.pen.tracker`, so the page never has a
copy of its own.

A surface of a material (docs/surfaces.md, "Materials") is written as it is rendered:
its heights in metres (the material's relief scale and hardness already in them), its
prominence floor and full prominence in metres, and its micro-roughness as the
parameters of :class:`~tactilize.materials.MicroRoughness`, which the page draws where
the pen is as Python does (it lies below the model's pixels, so it is not in the heights).

Layout (little-endian)::

    b"TSF1"                      magic
    uint32                       N, the header's length in bytes
    N bytes                      the header, JSON (UTF-8)
    the rest                     zlib stream of rows x cols bytes: the residuals of
                                 the header's predictor ("left" or "gradient"),
                                 modulo 256, row by row

Height of a pixel = ``offset + q * scale`` (float64 arithmetic), rounded to float32:
Python (:func:`read_model`) and JavaScript compute it the same way, so both renderers
see the same heights to the bit.

Units: SI (m, s, Hz); heights in luminance units, or metres for a material.
"""

from __future__ import annotations

import json
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ImageError
from ..materials import MicroRoughness, Relief, material as library_material
from ..pen.tracker import StrokeTracker
from ..surface import events as _events
from ..surface import stroke as _stroke
from ..surface.model import SurfaceModel
from ..surface.path import HISTORY_M
from ..synthesis.acceleration import VOICE_COIL_BAND_HZ
from ..web.constants import page_constants

__all__ = ["MAGIC", "FORMAT_VERSION", "ModelFile", "rule_parameters", "encode_model", "decode_model",
           "read_model", "write_model"]

MAGIC = b"TSF1"
FORMAT_VERSION = 2
_PREDICTORS = ("left", "gradient")


def rule_parameters() -> dict[str, Any]:
    """Every parameter of the surface rule the page runs, from the Python renderer's own constants."""
    tr = StrokeTracker()
    return {
        "lookahead_s": _stroke.LOOKAHEAD_S,
        "late_s": _stroke.LATE_S,
        "same_bump_share": _stroke.SAME_BUMP_SHARE,
        "max_gap_s": _stroke.MAX_GAP_S,
        "still_speed_m_s": _stroke.STILL_SPEED_M_S,
        "max_ahead_m": _stroke.MAX_AHEAD_M,
        "fired_kept": _stroke.FIRED_KEPT,
        "history_m": HISTORY_M,
        "rate_only_hz": _events.RATE_ONLY_HZ,
        "min_interval_s": _events.MIN_INTERVAL_S,
        "cluster_interval_s": _events.CLUSTER_INTERVAL_S,
        "reference_pressure": _events.REFERENCE_PRESSURE,
        "wavelet_band_hz": list(VOICE_COIL_BAND_HZ),
        # the audio worklet's rule for the wavelets, as the pen page is served it
        "wavelet": page_constants()["wavelet"],
        "tracker": {
            "window_s": tr.window_s, "min_samples": tr.min_samples, "min_travel_m": tr.min_travel_m,
            "max_window_s": tr.max_window_s, "max_gap_s": tr.max_gap_s, "max_speed_m_s": tr.max_speed_m_s,
            "still_speed_m_s": tr.still_speed_m_s, "max_samples": tr._buf.maxlen,
        },
    }


@dataclass(frozen=True)
class ModelFile:
    """A decoded model file.

    Attributes
    ----------
    header : dict
        The JSON header (scale, material, parameters).
    levels : ndarray of uint8, shape (rows, cols)
        The quantised heights.
    """

    header: dict[str, Any]
    levels: np.ndarray

    @property
    def heights(self) -> np.ndarray:
        """Heights [luminance units, or m for a material], float32, as the page computes them."""
        h = self.header
        return (float(h["offset"]) + self.levels.astype(np.float64) * float(h["scale"])).astype(np.float32)

    def surface(self, display_pitch_m: float | tuple[float, float] | None = None) -> SurfaceModel:
        """The :class:`SurfaceModel` the page renders: these heights (already tip-filtered and
        scaled, so used as they are; not for :meth:`SurfaceModel.at_scale`), the file's prominence
        floor, relief and micro-roughness, shown at ``display_pitch_m`` [m per model pixel] (the
        file's own by default); the real scale stays the file's."""
        h = self.header
        disp = h["display_pitch_m"] if display_pitch_m is None else display_pitch_m
        vals = [float(v) for v in np.broadcast_to(np.asarray(disp, dtype=np.float64), (2,))]
        pair = (vals[0], vals[1])
        surf = (float(h["surface_pitch_m"][0]), float(h["surface_pitch_m"][1]))
        heights = self.heights
        relief = None
        if h.get("relief_scale_m") is not None:
            mat = library_material(h["material"]) if h.get("material") else None
            relief = Relief(float(h["relief_scale_m"]), "given", mat)
        m = h.get("micro")
        micro = None if m is None else MicroRoughness(float(m["rms_m"]), float(m["correlation_length_m"]),
                                                      float(m["filter_sigma_m"]), int(m["seed"]))
        return SurfaceModel(heights, pair, surf, float(h["tip_radius_m"]), float(h["prominence_floor"]), heights,
                            relief, micro)


def _residuals(q: np.ndarray, predictor: str) -> np.ndarray:
    """Residuals (mod 256) of ``q`` under ``predictor``; :func:`_undo` inverts them."""
    v = q.astype(np.int16)
    pred = np.zeros_like(v)
    pred[:, 1:] = v[:, :-1]
    if predictor == "gradient":
        # Left + up - up-left; the first column predicts from above.
        pred[1:, 1:] = v[1:, :-1] + v[:-1, 1:] - v[:-1, :-1]
        pred[1:, 0] = v[:-1, 0]
    return ((v - pred) & 0xFF).astype(np.uint8)


def _undo(r: np.ndarray, predictor: str) -> np.ndarray:
    rows, cols = r.shape
    out = np.zeros((rows, cols), dtype=np.int64)
    ri = r.astype(np.int64)
    for y in range(rows):
        if predictor == "gradient" and y > 0:
            out[y, 0] = (out[y - 1, 0] + ri[y, 0]) & 0xFF
            for x in range(1, cols):
                out[y, x] = (out[y, x - 1] + out[y - 1, x] - out[y - 1, x - 1] + ri[y, x]) & 0xFF
        else:
            out[y] = np.cumsum(ri[y]) & 0xFF
    return out.astype(np.uint8)


def encode_model(surface: SurfaceModel, *, product_id: str | None = None, rendered_as: str | None = None) -> bytes:
    """The model file of ``surface`` (its tip-filtered heights quantised to 8 bits over their range).

    Parameters
    ----------
    surface : SurfaceModel
        At the resolution the page renders at; of a material or a relief scale, its heights
        are in metres, and the header says so (``material``, ``relief_scale_m`` [m per
        luminance unit], ``full_prominence`` [m], ``micro``).
    product_id : str, optional
        The catalogue id, for the header.
    rendered_as : str, optional
        What the surface is rendered as, in words
        (:meth:`~tactilize.materials.MaterialChoice.label`), for the header.

    Returns
    -------
    bytes
    """
    h = np.asarray(surface.height, dtype=np.float64)
    relief = surface.relief
    lo, hi = float(h.min()), float(h.max())
    scale = (hi - lo) / 255.0 if hi > lo else 1.0 / 255.0
    q = np.clip(np.round((h - lo) / scale), 0, 255).astype(np.uint8)
    best = b""
    chosen = _PREDICTORS[0]
    for predictor in _PREDICTORS:
        packed = zlib.compress(_residuals(q, predictor).tobytes(), 9)
        if not best or len(packed) < len(best):
            best, chosen = packed, predictor
    rows, cols = q.shape
    header = {
        "format": "tactilize-surface",
        "version": FORMAT_VERSION,
        "id": product_id,
        "cols": int(cols),
        "rows": int(rows),
        "offset": lo,
        "scale": scale,
        "predictor": chosen,
        "display_pitch_m": list(surface.display_pitch_m),
        "surface_pitch_m": list(surface.surface_pitch_m),
        "tip_radius_m": surface.tip_radius_m,
        "prominence_floor": surface.prominence_floor,
        # Strength is the bump's place from the floor to this (luminance units, or m for a material).
        "full_prominence": _events.full_prominence(surface),
        "material": None if relief is None or relief.material is None else relief.material.name,
        "relief_scale_m": None if relief is None else relief.scale_m,
        "micro": None if surface.micro is None else surface.micro.to_dict(),
        "rendered_as": rendered_as,
        "rule": rule_parameters(),
    }
    text = json.dumps(header, separators=(",", ":")).encode("utf-8")
    return MAGIC + struct.pack("<I", len(text)) + text + best


def decode_model(data: bytes, source: str = "<model>") -> ModelFile:
    """Read a model file's bytes.

    Raises
    ------
    ImageError
        Not a model file of this version, or damaged.
    """
    if len(data) < 8 or data[:4] != MAGIC:
        raise ImageError(source, "not a tactilize surface model (no TSF1 magic)")
    (n,) = struct.unpack("<I", data[4:8])
    try:
        header = json.loads(data[8 : 8 + n].decode("utf-8"))
        raw = zlib.decompress(data[8 + n :])
    except (UnicodeDecodeError, json.JSONDecodeError, zlib.error) as exc:
        raise ImageError(source, f"damaged model file ({exc.__class__.__name__})") from None
    if header.get("version") != FORMAT_VERSION or header.get("predictor") not in _PREDICTORS:
        raise ImageError(source, f"model file version {header.get('version')!r} is not {FORMAT_VERSION}")
    rows, cols = int(header["rows"]), int(header["cols"])
    if len(raw) != rows * cols:
        raise ImageError(source, f"holds {len(raw)} heights, not {rows} x {cols}")
    levels = _undo(np.frombuffer(raw, dtype=np.uint8).reshape(rows, cols), header["predictor"])
    return ModelFile(header, levels)


def write_model(path: str | Path, surface: SurfaceModel, **kw: Any) -> int:
    """Write :func:`encode_model` to ``path``; returns its size [bytes]."""
    data = encode_model(surface, **kw)
    Path(path).write_bytes(data)
    return len(data)


def read_model(path: str | Path) -> ModelFile:
    """:func:`decode_model` of a file."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ImageError(str(p), f"cannot read ({exc.strerror or exc.__class__.__name__})") from None
    return decode_model(data, str(p))
