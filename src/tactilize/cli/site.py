"""``tactilize site``: a catalogue as a static site whose photos can be felt on a phone (docs/shop.md)."""

from __future__ import annotations

import click

from ..errors import check_finite

__all__ = ["site"]


@click.command()
@click.argument("catalog")
@click.option("-o", "--out", "out", required=True, help="Folder to write the site into (made if missing).")
@click.option("--title", default="Products", show_default=True, help="The product grid's title.")
@click.option("--model-px", type=int, default=None, help="Long side of each surface model [px] [default: 384].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON summary at the end.")
def site(catalog: str, out: str, title: str, model_px: int | None, as_json: bool) -> None:
    """Write a static site for CATALOG (a folder, glob or manifest, as `batch` takes): index.html,
    a page per product, the surface models and the <tactile-surface> element.  Any web server
    hosts it (python -m http.server is enough)."""
    from ..site import MODEL_PX, build_site

    if model_px is not None:
        check_finite(model_px, "--model-px", above=15.0)
    summary = build_site(catalog, out, title=title, model_px=model_px or MODEL_PX)
    for ident, reason in summary.failed:
        click.echo(f"tactilize: {ident}: {reason} (left out)", err=True)
    if as_json:
        from . import emit_json

        emit_json({"out": str(summary.out), "products": len(summary.products), "failed": len(summary.failed),
                   "largest_model_bytes": summary.largest_model_bytes})
        return
    click.echo(f"{summary.out}: {len(summary.products)} products, {len(summary.failed)} left out, "
               f"largest model {summary.largest_model_bytes / 1024:.1f} KB; open {summary.out / 'index.html'} "
               f"through any web server (python -m http.server -d {summary.out})")
