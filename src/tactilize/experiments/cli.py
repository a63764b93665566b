"""``tactilize experiment ...``: the command line of the experiments package.

Thin, as the main CLI: parse, call the library, print.  Registered on the main
group by ``tactilize.cli``, so it is imported by every ``tactilize`` command:
each command imports the modules it calls (the store, the web app, the
analysis) when it runs, and ``tactilize --help`` loads none of them.  Errors are :class:`~tactilize.errors.TactilizeError`
and become one line and exit status 2 there.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from ..errors import TactilizeError, check_output_path
from ..encode import dumps

DB_HELP = "SQLAlchemy URL or SQLite file (default: experiments.sqlite3 in the user data directory)."


def _emit(doc) -> None:
    click.echo(dumps(doc))


@click.group()
def experiment() -> None:
    """Run the paper's user experiments: protocols, sessions, exports, analysis."""


@experiment.command("protocols")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def protocols_cmd(as_json: bool) -> None:
    """List the built-in protocols."""
    from .design_toml import builtin_designs

    protos = builtin_designs()
    if as_json:
        _emit([p.to_dict() for p in protos])
        return
    width = max(len(p.name) for p in protos)  # the columns line up whatever the names
    for p in protos:
        counts = "  ".join(_count(k, what) for k, what in ((len(p.conditions), "condition"), (len(p.images), "image"),
                                                          (len(p.questions), "question"), (len(p.plan(1)), "trial")))
        click.echo(f"{p.name:<{width}}  v{p.version}  {counts}  n = {p.participants_planned:<3} {p.title}")


def _count(n: int, noun: str) -> str:
    """``3 images``, `` 1 image ``: padded to one width, so that the columns line up."""
    return f"{n:>2} " + f"{noun}{'s' * (n != 1)}".ljust(len(noun) + 1)


@experiment.command("run")
@click.argument("protocols", nargs=-1, required=True)
@click.option("--db", "db_url", default=None, help=DB_HELP)
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to bind (beyond loopback a token is required).")
@click.option("--port", default=8765, show_default=True, type=int)
@click.option("--token", default=None, help="Experimenter token (generated and printed when not given).")
@click.option("--output", "output_spec", default="simulated", show_default=True, help="simulated | serial:PORT | audio[:DEVICE]")
@click.option("--open/--no-open", "open_browser", default=None,
              help="Open the experimenter's page in a browser [default: when a display exists].")
def run_cmd(protocols: tuple[str, ...], db_url: str | None, host: str, port: int, token: str | None,
            output_spec: str, open_browser: bool | None) -> None:
    """Serve the participant flow of PROTOCOLS (built-in names or TOML files).

    Several protocols make one visit: each participant takes them in the order
    given (e.g. g-law h-law alpha-law assessment) with one calibration.

    The pages are at /experiment/ (participant) and /experiment/admin
    (experimenter), inside the pen app; the conditions' drives go to --output.
    """
    from .design_toml import load_design
    from .web import serve_flow

    if not 0 <= port < 65536:
        raise TactilizeError("--port", f"must be 0 .. 65535, got {port}")
    serve_flow([load_design(p) for p in protocols], db_url, host=host, port=port, admin_token=token, output=output_spec,
               echo=click.echo, warn=lambda s: click.echo(s, err=True), open_browser=open_browser)


@experiment.command("status")
@click.option("--db", "db_url", default=None, help=DB_HELP)
@click.option("--protocol", "protocol_name", default=None, help="Only this protocol.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def status_cmd(db_url: str | None, protocol_name: str | None, as_json: bool) -> None:
    """Sessions and their progress."""
    from .store import Store

    store = Store(db_url, must_exist=True)
    store.require_protocol(protocol_name)
    rows = store.sessions_overview(protocol_name)
    if as_json:
        _emit({"db": _redact(store.url), "sessions": rows})
        return
    if not rows:
        click.echo(f"no sessions in {_redact(store.url)}")
        return
    for r in rows:
        state = "done" if r["completed_at"] else f"{r['trials_done']}/{r['trials_total']}"
        click.echo(f"{r['protocol']:<11} {r['participant']:<16} #{r['participant_number']:<3} {state:<8} "
                   f"{r['stroke_samples']:>6} samples  started {r['created_at']}"
                   + ("  (simulated)" if r["simulated"] else "") + ("  (excluded)" if r["excluded"] else ""))


@experiment.command("export")
@click.option("--db", "db_url", default=None, help=DB_HELP)
@click.option("--format", "fmt", type=click.Choice(["csv", "json", "wide", "parquet"]), default="csv", show_default=True,
              help="csv/json: one row per answer; wide: one row per participant (SPSS/JASP); parquet: the csv rows.")
@click.option("--protocol", "protocol_name", default=None, help="Only this protocol.")
@click.option("-o", "--output", default=None, help="Write to this file (default: stdout).")
@click.option("--strokes", is_flag=True, help="Export the stroke log (pen samples and drives) instead of the answers.")
def export_cmd(db_url: str | None, fmt: str, protocol_name: str | None, output: str | None, strokes: bool) -> None:
    """Export the answers: tidy CSV (one row per answer) or JSON with provenance."""
    from .analysis import export_answers, export_strokes
    from .store import Store, provenance

    if output is not None:
        check_output_path(output)
    store = Store(db_url, must_exist=True)
    store.require_protocol(protocol_name)
    if fmt == "parquet":
        from .analysis import tidy_answers

        if output is None:
            raise TactilizeError("--format parquet", "needs -o FILE (Parquet is binary)")
        if strokes:
            raise TactilizeError("--format parquet", "is for the answers; export --strokes as csv or json")
        from ..extras import require

        require("pyarrow", "--format parquet", "experiments")
        try:
            tidy_answers(store, protocol_name).to_parquet(output, index=False)
        except OSError as exc:
            raise TactilizeError(output, f"cannot write ({exc.strerror or exc})") from None
        click.echo(f"wrote {output}")
        return
    if fmt == "wide":
        from .analysis import tidy_answers
        from .labdata import wide_table

        if strokes:
            raise TactilizeError("--format wide", "is for the answers; export --strokes as csv or json")
        from .demographics import all_answers

        answers = tidy_answers(store, protocol_name)
        pnames = sorted(answers["protocol"].unique())
        if len(pnames) > 1:
            # Each protocol has its own conditions and questions: one table each, never
            # one table whose columns are half empty for every participant.
            if output is None:
                raise TactilizeError("--format wide", f"the store holds {len(pnames)} protocols ({', '.join(pnames)}): "
                                                      "give --protocol NAME, or -o FILE for one file per protocol")
            demographics = all_answers(store)
            for pname in pnames:
                path = _per_protocol(output, pname)
                _write(path, wide_table(answers[answers["protocol"] == pname], demographics)
                       .to_csv(index=False, lineterminator="\n"), provenance(protocol_filter=pname))
                click.echo(f"wrote {path}")
            return
        text = wide_table(answers, all_answers(store)).to_csv(index=False, lineterminator="\n")
    else:
        text = export_strokes(store, fmt, protocol_name) if strokes else export_answers(store, fmt, protocol_name)
    if output is None:
        sys.stdout.write(text)
        return
    _write(output, text, provenance(protocol_filter=protocol_name) if fmt in ("csv", "wide") else None)
    click.echo(f"wrote {output}")


def _per_protocol(output: str, pname: str) -> str:
    """``answers.csv`` -> ``answers-g-law.csv``: one protocol's file beside the name asked for."""
    path = Path(output)
    return str(path.with_name(f"{path.stem}-{pname}{path.suffix}"))


def _write(output: str, text: str, prov: dict | None) -> None:
    """Write ``text``; a CSV's provenance goes beside it (CSV has no place for
    metadata that every reader skips)."""
    try:
        Path(output).write_text(text, "utf-8")
        if prov is not None:
            Path(output + ".provenance.json").write_text(json.dumps(prov, indent=2), "utf-8")
    except OSError as exc:
        raise TactilizeError(output, f"cannot write ({exc.strerror or exc})") from None


@experiment.command("analyze")
@click.option("--db", "db_url", default=None, help=DB_HELP)
@click.option("--protocol", "protocol_name", default=None, help="Only this protocol.")
@click.option("--figures", "figures_dir", default=None, help="Write PNG (300 dpi), PDF and SVG figures into this directory.")
@click.option("--figure-width", type=click.Choice(["single", "double"]), default="double", show_default=True,
              help="Figures one (89 mm) or two (183 mm) journal columns wide.")
@click.option("--include-simulated", is_flag=True, help="Count simulated participants too (left out by default).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def analyze_cmd(db_url: str | None, protocol_name: str | None, figures_dir: str | None, figure_width: str,
                include_simulated: bool, as_json: bool) -> None:
    """Descriptives, Friedman (F) with Kendall's W, Wilcoxon with Holm; optional figures."""
    from .analysis import analyze
    from .store import Store

    if figures_dir:
        check_output_path(figures_dir, folder=True)
    store = Store(db_url, must_exist=True)
    store.require_protocol(protocol_name)
    result = analyze(store, protocol_name, include_simulated=include_simulated)
    if not result["protocols"]:
        raise TactilizeError(_redact(store.url), "no answers to analyse" + (f" for {protocol_name}" if protocol_name else "")
                             + ("" if include_simulated else " from real participants (simulated ones are left out; "
                                "add --include-simulated)"))
    if figures_dir:
        from .figures import make_figures

        result["figures"] = make_figures(store, figures_dir, protocol_name, include_simulated=include_simulated,
                                         width=figure_width)
    if as_json:
        _emit(result)
        return
    for pname, pres in result["protocols"].items():
        click.echo(f"{pname}: {pres['n_participants']} participants, {pres['n_answers']} answers")
        for qid, q in pres["questions"].items():
            click.echo(f"  {qid}")
            names = {cid: f"{cid}  {pres['condition_labels'].get(cid, cid)}" if pres["condition_labels"].get(cid, cid) != cid
                     else cid for cid in q["descriptives"]}
            width = max(8, *(len(n) for n in names.values()))
            for cid, d in q["descriptives"].items():
                sd = f"{d['sd']:.2f}" if d["sd"] is not None else "-"
                click.echo(f"    {names[cid]:<{width}}  n={d['n']:<3} median {d['median']:.1f} (IQR {d['iqr']:.2f})  "
                           f"mean {d['mean']:.2f} SD {sd}")
            fr = q["friedman"]
            if fr and fr.get("F") is not None:
                click.echo(f"    Friedman F({fr['ddof1']:.2f}, {fr['ddof2']:.2f}) = {fr['F']:.2f}, p = {fr['p']:.3g}, "
                           f"Kendall's W = {fr['W']:.2f} (chi2 = {fr['Q']:.2f}, p = {fr['p_chisq']:.3g}; n = {fr['n']})")
            sig = [p for p in q["pairwise"] if p.get("significant_0_05")]
            if q["pairwise"]:
                click.echo(f"    Wilcoxon/Holm: {len(sig)} of {len(q['pairwise'])} pairs differ at 0.05"
                           + ("".join(f"\n      {p['a']} vs {p['b']}: p_holm = {p['p_holm']:.3g}, "
                                      f"r_rb = {p['rbc']:.2f}" for p in sig[:12])))
    for pname, files in result.get("figures", {}).items():
        click.echo(f"figure {pname}: {files['png']}, {files['pdf']}, {files['svg']}")


@experiment.command("simulate")
@click.argument("protocol")
@click.option("--participants", type=int, required=True, help="Number of synthetic participants.")
@click.option("--seed", type=int, required=True, help="Seed of their random streams.")
@click.option("--db", "db_url", default=None, help=DB_HELP)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def simulate_cmd(protocol: str, participants: int, seed: int, db_url: str | None, as_json: bool) -> None:
    """Run synthetic participants through the server (resumable; see docs/experiments.md)."""
    from .simulate import simulate

    from .store import default_db_url

    summary = simulate(protocol, participants, seed, db_url)
    # Without --db the rows go to the user data folder, which nobody finds unless told.
    summary["db"] = _redact(default_db_url() if db_url is None else db_url)
    if as_json:
        _emit(summary)
        return
    click.echo(f"{summary['protocol']}: seed {seed}, {summary['started']} started, {summary['resumed']} resumed, "
               f"{summary['skipped']} already finished, {summary['trials_submitted']} trials submitted")
    click.echo(f"database {summary['db']}" + (" (the default; --db chooses another)" if db_url is None else ""))


@experiment.command("calibrate")
@click.argument("participant")
@click.option("-o", "--output", required=True, help="Profile TOML to write (use with `tactilize serve --profile`).")
@click.option("--db", "db_url", default=None, help=DB_HELP)
@click.option("--base", default="paper", show_default=True, help="Preset or TOML the fitted laws replace.")
@click.option("--question", "questions", multiple=True, help="Only these questions count (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def calibrate_cmd(participant: str, output: str, db_url: str | None, base: str, questions: tuple[str, ...],
                  as_json: bool) -> None:
    """Fit PARTICIPANT's own laws from their ratings and save them as a profile."""
    from .calibration import fit_personal_profile
    from .store import Store

    check_output_path(output)
    prof, report = fit_personal_profile(Store(db_url, must_exist=True), participant, base=base, questions=list(questions) or None)
    prof.save(output)
    report["output"] = output
    if as_json:
        _emit(report)
        return
    for f in report["fits"]:
        coef = ", ".join(f"{k} = {v:.4g}" for k, v in f.get("coefficient", {}).items())
        click.echo(f"{f['role']:<9} {f['law']:<8} {coef:<24} ({f['method']}; {f['protocol']})")
    click.echo(f"wrote {output}")


@experiment.command("refine")
@click.argument("participant")
@click.option("-o", "--output", required=True, help="Protocol TOML to write (then: experiment run FILE).")
@click.option("--db", "db_url", default=None, help=DB_HELP)
@click.option("--role", type=click.Choice(["frequency", "width", "speed"]), default=None,
              help="Which fitted law to refine (default: the last fitted).")
@click.option("--span-octaves", type=float, default=0.5, show_default=True, help="Grid half-width around the fit.")
@click.option("--steps", type=int, default=5, show_default=True, help="Grid points.")
@click.option("--repetitions", type=int, default=2, show_default=True)
def refine_cmd(participant: str, output: str, db_url: str | None, role: str | None, span_octaves: float, steps: int,
               repetitions: int) -> None:
    """Write a short protocol refining PARTICIPANT's fitted law (the adaptive step)."""
    from .calibration import refinement_protocol
    from .store import Store

    check_output_path(output)
    text = refinement_protocol(Store(db_url, must_exist=True), participant, role, span_octaves=span_octaves, steps=steps,
                               repetitions=repetitions)
    try:
        Path(output).write_text(text, "utf-8")
    except OSError as exc:
        raise TactilizeError(output, f"cannot write ({exc.strerror or exc})") from None
    click.echo(f"wrote {output}; run it with: tactilize experiment run {output}")


@experiment.command("backup")
@click.argument("target")
@click.option("--db", "db_url", default=None, help=DB_HELP)
def backup_cmd(target: str, db_url: str | None) -> None:
    """Copy the (SQLite) store to TARGET, safely while the server runs (SQLite's online backup)."""
    from .labdata import backup
    from .store import Store

    check_output_path(target)
    doc = backup(Store(db_url, must_exist=True), target)
    click.echo(f"wrote {doc['backup']}: {doc['answers']} answers")


@experiment.command("withdraw")
@click.argument("protocol")
@click.argument("participant")
@click.option("--db", "db_url", default=None, help=DB_HELP)
@click.option("--yes", is_flag=True, help="Do not ask for confirmation.")
def withdraw_cmd(protocol: str, participant: str, db_url: str | None, yes: bool) -> None:
    """Delete PARTICIPANT's data in PROTOCOL (a withdrawal of consent); cannot be undone."""
    from .labdata import withdraw
    from .store import Store

    store = Store(db_url, must_exist=True)
    store.require_protocol(protocol)
    if not yes:
        click.confirm(f"Delete every answer and stroke of {participant} in {protocol}?", abort=True)
    counts = withdraw(store, protocol, participant)
    click.echo(f"withdrew {participant} from {protocol}: " + ", ".join(f"{v} {k}" for k, v in counts.items()))


@experiment.command("exclude")
@click.argument("protocol")
@click.argument("participant")
@click.option("--reason", default="", help="Why (kept with the exclusion).")
@click.option("--db", "db_url", default=None, help=DB_HELP)
def exclude_cmd(protocol: str, participant: str, reason: str, db_url: str | None) -> None:
    """Exclude PARTICIPANT from PROTOCOL's analysis; the next participant takes their square row."""
    from .labdata import exclude
    from .store import Store

    store = Store(db_url, must_exist=True)
    store.require_protocol(protocol)
    doc = exclude(store, protocol, participant, reason)
    click.echo(f"excluded {participant} from {protocol}; the next participant gets square row "
               f"{doc['freed_square_number']}")


def _redact(url: str) -> str:
    from .analysis import _redact as r

    return r(url)
