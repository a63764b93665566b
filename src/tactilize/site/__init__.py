"""A shop's catalogue as a static site whose product photos can be felt on a phone (docs/shop.md).

:mod:`.model_file` writes (and reads) the compact surface model a page loads;
:mod:`.builder` makes the site from a catalogue source; :mod:`.from_catalog` makes
it from a catalogue ``tactilize batch`` wrote; :mod:`.routes` serves a built site
from ``tactilize serve``.  The rendering itself runs in the browser
(``static/surface-rule.js``), by the rule of :mod:`tactilize.surface`.
"""

from __future__ import annotations

from .builder import MAX_MODEL_BYTES, MODEL_PX, SiteSummary, build_site, model_bytes
from .model_file import ModelFile, decode_model, encode_model, read_model, rule_parameters, write_model

__all__ = ["MAX_MODEL_BYTES", "MODEL_PX", "ModelFile", "SiteSummary", "build_site", "decode_model", "encode_model",
           "model_bytes", "read_model", "rule_parameters", "write_model"]
