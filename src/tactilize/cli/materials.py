"""``tactilize materials`` and the ``--material`` option the surface commands share.

The library is :mod:`tactilize.materials`; every number's source is in
docs/references.md, section 11 (material library).
"""

from __future__ import annotations

from typing import Any

import click

from ..errors import TactilizeError

__all__ = ["materials_cmd", "material_option", "check_material", "describe_relief", "choice_of", "surface_only"]


def check_material(ctx: Any, param: Any, value: str | None) -> str | None:
    """The ``--material`` callback: an unknown name is refused before any work."""
    if value is None:
        return None
    from ..materials import material

    return material(value).name


def check_relief_mm(ctx: Any, param: Any, value: float | None) -> float | None:
    """The ``--relief-mm`` callback: a positive finite number of millimetres."""
    if value is None:
        return None
    from ..catalog.sources import check_relief_mm as check  # the one rule, a manifest's relief_mm's too

    return check(value, "--relief-mm")


def material_option(func: Any) -> Any:
    """``--material NAME`` and ``--relief-mm MM``: what the picture shows is made of, and how
    deep its relief is (docs/surfaces.md, "Materials")."""
    func = click.option(
        "--relief-mm", "relief_mm", type=float, default=None, callback=check_relief_mm,
        help="RMS height of the picture's visible relief [mm] (its luminance less what varies slower than "
             "5 mm): heights in metres at this relief, overriding the material's typical one.")(func)
    return click.option(
        "--material", "material_name", default=None, callback=check_material,
        help="What the picture is of, from the material library (`tactilize materials`): heights in metres, "
             "its hardness and micro-roughness. Without it the picture alone renders.")(func)


def choice_of(material_name: str | None, relief_mm: float | None) -> Any:
    """The :class:`~tactilize.materials.MaterialChoice` of ``--material`` and ``--relief-mm`` [mm]."""
    from ..materials import MaterialChoice

    return MaterialChoice.of(material_name, None if relief_mm is None else relief_mm * 1e-3)


def describe_relief(surface: Any, choice: Any = None) -> dict[str, Any]:
    """The ``material``, ``relief_scale_m`` and ``relief_source`` of a surface for a JSON
    document (the picture alone: ``material`` None, ``relief_source`` "picture"); with the
    :class:`~tactilize.materials.MaterialChoice` it was made with, also ``relief_rms_m``
    (given, or None) and ``rendered_as`` (in words)."""
    relief = getattr(surface, "relief", None)
    doc = {"material": None, "relief_scale_m": None, "relief_source": "picture"} if relief is None \
        else relief.describe()
    if choice is not None:
        doc.update(choice.to_dict())
    return doc


def surface_only(choice: Any, profile: Any) -> None:
    """A material or a relief changes only a rendering that reads the picture as a surface; with
    another it would be ignored (``choice``: a :class:`~tactilize.materials.MaterialChoice`; the
    profile's rendering is asked, :func:`~tactilize.surface.rendering.rendering_kind`, before any
    picture is read)."""
    from ..surface.rendering import rendering_kind

    rendering = rendering_kind(profile)
    if not choice.picture_only and not rendering.reads_surface:
        which = "--material" if choice.material is not None else "--relief-mm"
        raise TactilizeError(which, f"needs a surface profile (this one's rendering is {rendering.name!r})")


@click.command("materials")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document: a list, one object per material.")
def materials_cmd(as_json: bool) -> None:
    """List the material library: relief, micro-roughness, hardness and friction, with sources."""
    from ..encode import dumps
    from ..materials import contact_radius_m, library
    from ..surface.model import TIP_RADIUS_M

    rows = []
    for m in library().values():
        rows.append({**m.to_dict(), "contact_radius_m": contact_radius_m(m, TIP_RADIUS_M)})
    if as_json:
        click.echo(dumps(rows))
        return
    click.echo(f"{'material':<18} {'relief um':>9} {'micro um':>8} {'corr um':>7} {'E* Pa':>8} {'layer mm':>8} "
               f"{'contact um':>10} {'mu':>5}  (sources: docs/references.md, section 11)")
    for r in rows:
        click.echo(f"{r['name']:<18} {r['relief_rms_m'] * 1e6:>9.3g} {r['micro_rms_m'] * 1e6:>8.3g} "
                   f"{r['micro_correlation_m'] * 1e6:>7.3g} {r['modulus_pa']:>8.2g} {r['thickness_m'] * 1e3:>8.3g} "
                   f"{r['contact_radius_m'] * 1e6:>10.3g} {r['friction']:>5.2f}  {r['description']}")
        for key, text in r["sources"].items():
            click.echo(f"{'':<20}{key}: {text}")
