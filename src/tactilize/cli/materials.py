"""``tactilize materials`` and the ``--material`` option the surface commands share.

The library is :mod:`tactilize.materials`; every number's source is in
docs/references.md, section 11 (material library).
"""

from __future__ import annotations

from typing import Any

import click

from ..errors import TactilizeError

__all__ = ["materials_cmd", "material_option", "check_material", "describe_relief"]


def check_material(ctx: Any, param: Any, value: str | None) -> str | None:
    """The ``--material`` callback: an unknown name is refused before any work."""
    if value is None:
        return None
    from ..materials import material

    return material(value).name


def material_option(func: Any) -> Any:
    """``--material NAME``: what the picture shows is made of (docs/surfaces.md, "Materials")."""
    return click.option(
        "--material", "material_name", default=None, callback=check_material,
        help="What the picture is of, from the material library (`tactilize materials`): heights in metres, "
             "its hardness and micro-roughness. Without it the picture alone renders.")(func)


def describe_relief(surface: Any) -> dict[str, Any]:
    """The ``material``, ``relief_scale_m`` and ``relief_source`` of a surface for a JSON
    document (the picture alone: ``material`` None, ``relief_source`` "picture")."""
    relief = getattr(surface, "relief", None)
    if relief is None:
        return {"material": None, "relief_scale_m": None, "relief_source": "picture"}
    return relief.describe()


def surface_only(material_name: str | None, rendering: str) -> None:
    """A material changes the surface rendering only; with a steady profile it would be ignored."""
    if material_name is not None and rendering != "surface":
        raise TactilizeError("--material", f"needs a surface profile (this one's rendering is {rendering!r})")


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
