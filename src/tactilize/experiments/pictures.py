"""A design's pictures as the flow serves them: the PNG shown, the features driven, the surface felt.

A picture given by its features (the paper's tables) is shown as a rendered
stand-in (:mod:`.stimuli`) and drives with exactly the stated features; one
given by a file (``path``, next to the protocol file) is shown as it is and its
features are measured once, when the flow starts.
"""

from __future__ import annotations

import dataclasses
import threading
from pathlib import Path
from ..features import extract_features
from ..image import load_image
from ..mapping import DriveFeatures, FeaturesForDrive
from ..surface import SurfaceModel, surface_model
from .design import Design, ImageSpec
from .stimuli import PITCH_M, SIZE_PX, render_array, render_png

__all__ = ["Pictures"]


class Pictures:
    """The pictures of one design: features made at once, PNGs and surfaces on first use.

    Parameters
    ----------
    design : Design
    """

    def __init__(self, design: Design) -> None:
        self.design = design
        self.features: dict[str, FeaturesForDrive] = {im.id: self._features(im) for im in design.images}
        self._surfaces: dict[str, SurfaceModel] = {}
        self._sizes: dict[str, tuple[int, int]] = {}
        self._lock = threading.Lock()

    def resolve(self, im: ImageSpec) -> ImageSpec:
        """The image spec with its path made relative to the protocol file."""
        if im.path and self.design.source.endswith(".toml"):
            cand = Path(self.design.source).parent / im.path
            if cand.exists():
                return dataclasses.replace(im, path=str(cand))
        return im

    def _features(self, im: ImageSpec) -> FeaturesForDrive:
        path = self.resolve(im).path
        if path:
            return extract_features(load_image(path))
        return DriveFeatures(im.spatial_frequency_per_m, im.spectral_intensity, im.orientation_deg, im.anisotropy)

    def png(self, image_id: str) -> bytes:
        """The picture shown, as PNG bytes; raises the design's error for an unknown id."""
        return render_png(self.resolve(self.design.image(image_id)))

    def size_px(self, image_id: str) -> tuple[int, int]:
        """The picture's (width, height) in pixels as served, known before it is sent.

        The page reserves the picture's box from it, so the surface does not move
        under a stroke begun before the picture loaded.  A file is read for its
        header only; raises the design's error for an unknown id.
        """
        size = self._sizes.get(image_id)
        if size is None:
            im = self.resolve(self.design.image(image_id))
            if im.path:
                from PIL import Image

                with Image.open(im.path) as pic:
                    size = (int(pic.width), int(pic.height))
            else:
                size = (SIZE_PX[1], SIZE_PX[0])
            self._sizes[image_id] = size
        return size

    def display_mm(self, image_id: str) -> tuple[float, float]:
        """The picture's (width, height) on screen [mm]: every picture is shown at
        :data:`.stimuli.PITCH_M` per pixel (its true size for a stand-in)."""
        w, h = self.size_px(image_id)
        return (w * PITCH_M * 1e3, h * PITCH_M * 1e3)

    def surface(self, image_id: str) -> SurfaceModel:
        """The surface model of a picture as shown (for a condition whose profile renders
        ``surface``), made on first use and kept."""
        with self._lock:
            surf = self._surfaces.get(image_id)
            if surf is None:
                im = self.resolve(self.design.image(image_id))
                if im.path:
                    surf = surface_model(load_image(im.path))
                else:  # the stand-in the page shows, at its pitch (the page scales it to true size)
                    surf = surface_model(render_array(im), pitch_m=PITCH_M)
                self._surfaces[image_id] = surf
        return surf
