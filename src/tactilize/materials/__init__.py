"""Materials: what a photograph of a surface cannot show (docs/surfaces.md, "Materials").

- :mod:`.library`: the material library (``library.toml``), :func:`material` by name;
- :mod:`.choice`: what a picture is rendered as (:class:`MaterialChoice`: picture only, or a
  material and its relief), as the commands, the pen server and the catalogue name it;
- :mod:`.relief`: a picture's relief scale in metres and the hardness of its material;
- :mod:`.roughness`: the micro-roughness below a picture's resolution, drawn by position;
- :mod:`.threshold`: the vibrotactile detection threshold in displacement and acceleration.

Every number's source: docs/references.md, section 11 (material library).
"""

from .choice import PICTURE_ONLY, MaterialChoice
from .library import Material, library, material, material_names
from .relief import (FULL_PROMINENCE_M, FULL_SCALE_ACCELERATION_M_S2, Relief, contact_radius_m, relief_for)
from .roughness import MicroRoughness
from .threshold import (LEAST_FELT_PROMINENCE_M, sensation_ratio, threshold_acceleration_m_s2,
                        threshold_displacement_m)

__all__ = [
    "Material", "MaterialChoice", "PICTURE_ONLY", "library", "material", "material_names", "Relief", "relief_for", "contact_radius_m",
    "MicroRoughness", "FULL_SCALE_ACCELERATION_M_S2", "FULL_PROMINENCE_M", "LEAST_FELT_PROMINENCE_M",
    "sensation_ratio", "threshold_acceleration_m_s2", "threshold_displacement_m",
]
