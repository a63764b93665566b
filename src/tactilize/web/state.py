"""The pen server's shared state: the pictures it shows and what every request and session reads.

:class:`ServerState` holds the output (one device, shared), the default profile,
the gallery (:class:`TextureEntry`: built-ins and uploads, each made on first
use), the latency ring and the work gates.  It lives at
``app.state.tactilize``; the /api routes (:mod:`.api`), the pen socket
(:mod:`.session`) and the output lease (:mod:`.ownership`) read it, so it sits
below all of them and imports none of them.

Units: SI (m); the page's CSS pixels only through ``m_per_px`` [m].
"""

from __future__ import annotations

import collections
import hashlib
import logging
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from ..actuators.base import Output
from ..encode import jsonable
from ..errors import ProfileError
from ..mapping import Profile, preset_names
from ..materials import MaterialChoice
from .limits import MAX_UPLOAD_PIXELS
from .rows import DEFAULT_M_PER_CSS_PX

if TYPE_CHECKING:  # the maps and the surfaces load the FFT stack: not at import
    from ..data import BuiltinTexture
    from ..maps.texturemap import TextureMap
    from ..surface.model import SurfaceModel

__all__ = ["ServerState", "TextureEntry", "MAX_UPLOADS", "MAX_RENDERINGS"]

log = logging.getLogger("tactilize.web")

#: Uploads kept in memory; the oldest is forgotten first.
MAX_UPLOADS = 24
#: Pictures kept rendered as another material than their own (the page's picker); the
#: oldest is forgotten first (a surface model is a few MB).
MAX_RENDERINGS = 24


class TextureEntry:
    """A picture the page can show: a built-in or an upload.

    The PNG and the texture map are made on first use (thread-safe, once), so
    listing textures is cheap and the server starts at once.

    Attributes
    ----------
    id, name, description : str
    width_m, height_m : float
        Physical size it is shown at [m].
    width_px, height_px : int
    builtin : bool
    material : MaterialChoice
        What its surface is rendered as (picture only, or a material and its relief).
    base : str
        The id of the picture it renders (its own id, unless it is a picture rendered as
        another material: :meth:`ServerState.rendered`).
    """

    def __init__(
        self,
        id: str,
        name: str,
        description: str,
        width_m: float,
        height_m: float,
        width_px: int,
        height_px: int,
        builtin: bool,
        make_png: Callable[[], bytes],
        make_map: Callable[[], TextureMap],
        make_surface: Callable[[], SurfaceModel] | None = None,
        material: MaterialChoice | None = None,
        make_image: Callable[[], Any] | None = None,
        base: str | None = None,
    ) -> None:
        self.id, self.name, self.description = id, name, description
        self.material = MaterialChoice() if material is None else material
        self.make_image = make_image
        self.base = id if base is None else base
        self.width_m, self.height_m = float(width_m), float(height_m)
        self.width_px, self.height_px = int(width_px), int(height_px)
        self.builtin = builtin
        self._make_png, self._make_map = make_png, make_map
        self._make_surface = make_surface
        self._surface: SurfaceModel | None = None
        self._png: bytes | None = None
        self._map: TextureMap | None = None
        self._lock = threading.Lock()

    @property
    def png(self) -> bytes:
        """The grey picture as PNG carrying its DPI (what was analysed is what is shown)."""
        if self._png is None:
            with self._lock:
                if self._png is None:
                    self._png = self._make_png()
        return self._png

    @property
    def map(self) -> TextureMap:
        """The :class:`~tactilize.maps.texturemap.TextureMap` at the displayed size."""
        if self._map is None:
            with self._lock:
                if self._map is None:
                    self._map = self._make_map()
        return self._map

    @property
    def surface(self) -> SurfaceModel | None:
        """The :class:`~tactilize.surface.SurfaceModel` at the displayed size (None when the
        entry has no picture to make one from)."""
        if self._surface is None and self._make_surface is not None:
            with self._lock:
                if self._surface is None:
                    self._surface = self._make_surface()
        return self._surface

    def describe(self, with_features: bool = True) -> dict[str, Any]:
        """JSON-ready listing entry (sizes in mm for the page, SI features)."""
        d: dict[str, Any] = {
            "id": self.id,
            "name": self.name,
            "description": self.description,
            "builtin": self.builtin,
            "width_mm": self.width_m * 1e3,
            "height_mm": self.height_m * 1e3,
            "width_px": self.width_px,
            "height_px": self.height_px,
            "url": f"/api/textures/{self.id}.png",
            "base": self.base,
            **self.material.to_dict(),
        }
        if with_features:
            d["features"] = jsonable(self.map.whole.to_dict())
        return d


class ServerState:
    """What every request and session shares.

    Parameters
    ----------
    output : Output
        Where drives go; shared by all sessions (it is one device).
    profile : Profile
        The default profile.
    m_per_px : float
        Default size of a CSS pixel [m] until the page sends its calibration.
    material : MaterialChoice, optional
        What the built-in pictures and uploads are rendered as unless the page picks another
        material (``serve --material``, ``--relief-mm``); picture only by default.
    """

    def __init__(self, output: Output, profile: Profile, m_per_px: float = DEFAULT_M_PER_CSS_PX, output_name: str = "",
                 material: MaterialChoice | None = None) -> None:
        self.output = output
        self.material = MaterialChoice() if material is None else material
        self.renderings: "collections.deque[str]" = collections.deque()
        self.output_name = output_name or type(output).__name__
        self.profile = profile
        self.m_per_px = float(m_per_px)
        self.textures: "collections.OrderedDict[str, TextureEntry]" = collections.OrderedDict()
        self.uploads: "collections.deque[str]" = collections.deque()
        self._builtin_ids: list[str] = []
        # Server-side latency of each rendered batch [ns]: arrival of the
        # message to its drive handed to the socket.  Bounded ring.
        self.latency_ns: "collections.deque[int]" = collections.deque(maxlen=20_000)
        self.counters: dict[str, int] = collections.Counter()
        self.sessions = 0
        #: makes one output per page (a simulated wire), or None: the pages take
        #: turns on ``output`` (web/ownership.py)
        self.page_output_factory: Callable[[], Output] | None = None
        #: the shared output's lease and the pages' idle outputs (web/ownership.py
        #: makes them on first use; typed there, not here, so this module imports none of it)
        self.output_lease: Any = None
        self.page_output_pool: Any = None
        from .limits import EXPORTS_ADMITTED, EXPORTS_RUNNING, UPLOADS_ADMITTED, UPLOADS_RUNNING, WorkGate

        #: heavy requests, bounded (web/limits.py)
        self.upload_gate = WorkGate("upload", UPLOADS_ADMITTED, UPLOADS_RUNNING)
        self.export_gate = WorkGate("stroke export", EXPORTS_ADMITTED, EXPORTS_RUNNING)
        from ..data import builtin_textures

        for t in builtin_textures():
            # The PNG and the map are built lazily (warm() does it at startup
            # off the event loop); only cheap metadata here.
            self.textures[t.id] = _builtin_entry(t, self.tip_radius_m, self.material)
            self._builtin_ids.append(t.id)

    @property
    def tip_radius_m(self) -> float:
        """The stylus tip radius [m] of every surface the server makes: its profile's
        (``serve --profile``; the presets' default otherwise)."""
        return float(self.profile.tip_radius_m)

    # ----------------------------------------------------------- profiles

    def profiles(self) -> dict[str, Profile]:
        """Profiles the page may pick: the presets plus the default (maybe a file)."""
        out = {}
        for name in preset_names():
            try:
                out[name] = Profile.preset(name)
            except ProfileError:  # a broken preset must not take the page down
                log.warning("preset %s does not load", name)
        out[self.profile.name] = self.profile
        return out

    def profile_named(self, name: str) -> Profile:
        """A profile by name (only presets and the default: the page cannot read files)."""
        if name == self.profile.name:
            return self.profile
        if name in preset_names():
            return Profile.preset(name)
        raise ProfileError(name, f"unknown profile (known: {', '.join(self.profiles())})")

    # ----------------------------------------------------------- textures

    def texture(self, texture_id: str) -> TextureEntry:
        """A texture by id; KeyError when unknown."""
        return self.textures[texture_id]

    def material_named(self, name: str | None) -> MaterialChoice:
        """What the page's picker names: None the server's own choice, ``""`` or ``"picture
        only"`` the picture alone, else a library material (at the server's given relief, if
        one was given: ``serve --relief-mm`` is the pictures' relief whatever they are made of).

        Raises
        ------
        MaterialError
            An unknown material (the message names it).
        """
        if name is None:
            return self.material
        chosen = MaterialChoice.of(name)
        return chosen if chosen.picture_only else MaterialChoice.of(chosen.material, self.material.relief_rms_m)

    def add_upload(self, data: bytes, filename: str, width_mm: float | None, dpi: float | None,
                   material: MaterialChoice | None = None) -> TextureEntry:
        """Validate, analyse and keep an uploaded picture (blocking: run in a thread), its
        surface rendered as ``material`` (the server's choice by default)."""
        from ..image import load_image
        from ..maps.texturemap import texture_map
        from ..data import png_bytes

        choice = self.material if material is None else material
        name = Path(filename or "upload").name[:80] or "upload"
        img = load_image(data, dpi=dpi, width_mm=width_mm, max_pixels=MAX_UPLOAD_PIXELS)
        digest = hashlib.sha256(data + repr((width_mm, dpi, choice.label())).encode()).hexdigest()[:12]
        tid = f"upload-{digest}"
        if tid in self.textures:
            return self.textures[tid]
        grey = (img.pixels * 255.0 + 0.5).astype("uint8")
        png = png_bytes(grey, img.dpi[0])
        tmap = texture_map(img)  # now, in the upload's thread: the first stroke must not wait
        from ..surface import surface_model

        # likewise (bench/bench_surfaces.py measures it)
        surface = surface_model(img, tip_radius_m=self.tip_radius_m, **choice.surface_kwargs())
        entry = TextureEntry(
            tid, name, f"Uploaded picture {name}", img.width_m, img.height_m, img.shape[1], img.shape[0], False,
            lambda: png, lambda: tmap, lambda: surface, choice, lambda: img,
        )
        self.textures[tid] = entry
        self.uploads.append(tid)
        while len(self.uploads) > MAX_UPLOADS:
            self.textures.pop(self.uploads.popleft(), None)
        return entry

    def rendered(self, texture_id: str, name: str | None) -> TextureEntry:
        """The picture of ``texture_id`` rendered as the material the page's picker names
        (:meth:`material_named`): the entry itself when it already is, else an entry of the
        same picture and map with its own surface (made now: blocking, run in a thread),
        kept among the last :data:`MAX_RENDERINGS`.

        Raises
        ------
        KeyError
            No such texture.
        MaterialError
            An unknown material.
        """
        entry = self.textures[texture_id]
        base = self.textures[entry.base]
        choice = self.material_named(name)
        if choice == base.material:
            return base
        rid = f"{base.id}~{choice.name or 'picture'}"
        if rid in self.textures:
            return self.textures[rid]
        if base.make_image is None:
            raise KeyError(texture_id)
        img = base.make_image()
        from ..surface import surface_model

        surface = surface_model(img, tip_radius_m=self.tip_radius_m, **choice.surface_kwargs())
        made = TextureEntry(
            rid, base.name, base.description, base.width_m, base.height_m, base.width_px, base.height_px,
            base.builtin, lambda: base.png, lambda: base.map, lambda: surface, choice, base.make_image, base.id,
        )
        self.textures[rid] = made
        self.renderings.append(rid)
        while len(self.renderings) > MAX_RENDERINGS:
            self.textures.pop(self.renderings.popleft(), None)
        return made

    def warm(self) -> None:
        """Generate every built-in picture, its map and its surface (about a second, once)."""
        from ..surface import stroke  # noqa: F401  (scipy.signal loaded now, not on a pen batch's path)

        for tid in self._builtin_ids:
            e = self.textures.get(tid)
            if e is not None:
                _made = e.png, e.map, e.surface

    # ----------------------------------------------------------- stats

    def stats(self, last: int | None = None) -> dict[str, Any]:
        """Latency percentiles [us] (over the ``last`` batches, or all kept) and counters."""
        lat = list(self.latency_ns)
        if last is not None and last > 0:
            lat = lat[-last:]
        lat.sort()

        def pct(p: float) -> float | None:
            if not lat:
                return None
            return lat[min(len(lat) - 1, int(p / 100.0 * len(lat)))] / 1e3

        return {
            "batches": len(lat),
            "server_latency_us": {"p50": pct(50), "p90": pct(90), "p99": pct(99), "max": lat[-1] / 1e3 if lat else None},
            "counters": dict(self.counters),
            "sessions": self.sessions,
        }


def _builtin_entry(t: BuiltinTexture, tip_radius_m: float, material: MaterialChoice) -> TextureEntry:
    from ..data import TEXTURE_SIZE_PX, builtin_map

    return TextureEntry(
        t.id, t.name, t.description, t.width_m, t.height_m, *TEXTURE_SIZE_PX, True,
        lambda: t.png, lambda: builtin_map(t.id), lambda: _surface_of(t, tip_radius_m, material), material,
        lambda: t.image,
    )


def _surface_of(t: BuiltinTexture, tip_radius_m: float, material: MaterialChoice) -> SurfaceModel:
    from ..surface import surface_model

    return surface_model(t.image, tip_radius_m=tip_radius_m, **material.surface_kwargs())
