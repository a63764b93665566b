"""`serve --profile`: the profile's stylus tip radius makes the page's surfaces (built-ins and uploads)."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image

from tactilize.mapping import Profile
from tactilize.web.app import ServerState


class _Out:
    channels = 2


def _png(size=64) -> bytes:
    buf = io.BytesIO()
    Image.fromarray((np.random.default_rng(0).random((size, size)) * 255).astype("uint8")).save(buf, format="PNG")
    return buf.getvalue()


def test_the_servers_profile_tip_radius_makes_every_surface():
    wide = Profile.preset("surface").replace(tip_radius_m=0.6e-3)
    state = ServerState(_Out(), wide)
    assert state.texture("sandpaper").surface.tip_radius_m == 0.6e-3
    assert state.add_upload(_png(), "x.png", 30.0, None).surface.tip_radius_m == 0.6e-3
    # The presets' default otherwise.
    plain = ServerState(_Out(), Profile.preset("surface"))
    assert plain.texture("sandpaper").surface.tip_radius_m == Profile.preset("surface").tip_radius_m != 0.6e-3
