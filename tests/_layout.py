"""Where an element is once the page has laid it out, for browser tests that stroke it."""

from __future__ import annotations

import time


def settled_box(page, selector: str, timeout_s: float = 30.0) -> dict:
    """The element's bounding box once every image on the page has loaded and the box
    stayed the same for 100 ms: a picture that loads late moves the surface under a
    stroke begun before it (the deadline is a bound only; a loaded machine is slow)."""
    page.wait_for_function("[...document.images].every((im) => im.complete)", timeout=timeout_s * 1000)
    box, previous = page.locator(selector).bounding_box(), None
    deadline = time.monotonic() + timeout_s
    while box != previous and time.monotonic() < deadline:
        page.wait_for_timeout(100)
        previous, box = box, page.locator(selector).bounding_box()
    assert box is not None, f"{selector} is not on the page"
    return box
