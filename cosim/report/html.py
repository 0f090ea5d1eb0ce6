"""``ehw report RUN_DIR``: ``report.html``, one self-contained page of a run folder.

Everything is embedded (PNGs and the replay as base64 ``data:`` URLs, the style inline), so the
file opens from disk with no network and no JavaScript. For a lifetime (``ehw sim``) or an
off-line run (``ehw offline``): the summary beside the paper's figures (``cosim.paper``), the
replay (``cosim.report.replay``: rendered once, reused while ``lifetime.npz`` is unchanged), the
learning curves, the world model, the evolved controller (truth table heat map and its 50 terms),
the run's own figures, and the configuration with the command that reproduces the run. For a
comparison (``ehw compare``): the table of every method and their box plots. The template is
``templates/report.html.j2`` (Jinja2, autoescaped).
"""

from __future__ import annotations

import base64
import datetime as _dt
import json
from pathlib import Path

import numpy as np

from base.errors import UserError
from base.files import atomic_write_text
from cosim.paper import PAPER_OFFLINE, PAPER_ONLINE
from cosim.report import figures
from cosim.report.replay import DEFAULT_FPS, DEFAULT_MAX_SECONDS, replay
from sim_world.recording import RECORDING, load_recording

REPORT = "report.html"
TEMPLATE = Path(__file__).with_name("templates") / "report.html.j2"
SUMMARY_LABELS = {"targets_reached": "targets reached", "interactions": "interactions",
                  "generations": "generations", "genetic_operations": "genetic operations",
                  "world_states": "world states", "transitions": "transitions"}
COMPARE_COLUMNS = ("interactions", "crashes", "targets_reached", "world_states", "transitions", "generations")
RUN_FIGURES = ("fig9_trajectory.png", "fig10_targets_states.png", "fig11_continued.png",
               "fig5_trajectory.png", "fig6_best_per_generation.png", "compare.png")


class ReportError(UserError, ValueError):
    """A folder that holds no run this report knows."""


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def _read_json(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _number(value) -> str:
    if isinstance(value, bool) or value is None:
        return "-" if value is None else str(value)
    if isinstance(value, float) and not value.is_integer():
        return f"{value:,.2f}"
    return f"{int(value):,}" if isinstance(value, (int, float)) else str(value)


def summary_rows(summary: dict, paper: dict) -> list[tuple[str, str, str, str]]:
    """(label, this run, the paper, ratio) for each figure the paper gives; a lifetime continued
    past 64 targets gives its figures at the 64th (``at_64_targets``), as its summary table does."""
    figures_at = dict(summary)
    at64 = summary.get("at_64_targets")
    if at64:
        figures_at.update({k: at64[k] for k in ("interactions", "generations", "world_states", "transitions")
                           if k in at64})
        figures_at["targets_reached"] = at64.get("target", 64)
        population = (summary.get("config") or {}).get("population")
        figures_at["genetic_operations"] = at64.get("generations", 0) * population if population else None
    rows = []
    for key, label in SUMMARY_LABELS.items():
        if key not in paper or figures_at.get(key) is None:
            continue
        ours, theirs = figures_at[key], paper[key]
        ratio = f"{ours / theirs:.2f}x" if isinstance(ours, (int, float)) and theirs else "-"
        rows.append((label, _number(ours), _number(theirs), ratio))
    return rows


def _notes(summary: dict, online: bool) -> list[str]:
    notes = []
    if online:
        reasons = ", ".join(f"{k} {v}" for k, v in summary.get("phase_reasons", {}).items())
        notes.append(f"{summary.get('learning_phases', 0)} learning phases (the paper: about 48): {reasons}; "
                     f"backend {summary.get('backend')}; wall time {summary.get('wall_time_s', 0):.1f} s.")
        if summary.get("at_64_targets"):
            notes.append(f"the table gives the figures at the 64th target; continued to {summary['targets_reached']} "
                         f"targets: {summary['interactions']:,} interactions, {summary['generations']:,} generations.")
    else:
        notes.append(f"reached every target: {summary.get('reached_all_targets')}; "
                     f"wall time {summary.get('wall_time_s', 0):.1f} s.")
        transfer = summary.get("transfer") or {}
        if transfer.get("targets_without_crash"):
            notes.append(f"in the noisy world, targets before a crash: {transfer['targets_without_crash']}")
    return notes


def _command(run_dir: Path) -> str:
    """The command of the config.toml header (``base.options.write_config``)."""
    try:
        lines = (run_dir / "config.toml").read_text().splitlines()
    except OSError:
        return "(no config.toml in the run folder)"
    return next((ln.lstrip("# ").strip() for ln in lines[:3] if ln.lstrip("# ").startswith("ehw ")),
                "(config.toml has no command line)")


def _video(run_dir: Path, fps: float, max_seconds: float, progress: bool) -> dict | None:
    """The replay, rendered unless one newer than the recording is there."""
    recording = run_dir / RECORDING
    if not recording.is_file():
        return None
    for kind in ("mp4", "gif"):
        made = run_dir / f"replay.{kind}"
        if made.is_file() and made.stat().st_mtime_ns >= recording.stat().st_mtime_ns:
            break
    else:
        made = replay(run_dir, fps=fps, max_seconds=max_seconds, progress=progress)
    kind = made.suffix.lstrip(".")
    return {"kind": kind, "data": _b64(made.read_bytes()),
            "caption": f"{made.name}: the robot with its heading and IR rays (red: the sensor's bit is 1), "
                       "the trail (the current leg darker), crashes (red x), targets reached (green dots); "
                       f"`ehw replay {run_dir}` renders it again (--fps, --max-seconds)."}


def _lifetime_context(run_dir: Path, summary: dict, fps: float, max_seconds: float, progress: bool) -> dict:
    online = str(summary.get("method", "")).startswith("online")
    ctx = {"summary_rows": summary_rows(summary, PAPER_ONLINE if online else PAPER_OFFLINE),
           "paper_section": "section 5.2, on-line" if online else "section 5.1, off-line",
           "summary_notes": _notes(summary, online)}
    rec = load_recording(run_dir) if (run_dir / RECORDING).is_file() else None
    ctx["video"] = _video(run_dir, fps, max_seconds, progress)
    if rec is not None and len(rec.curve_states):
        ctx["curves"] = _b64(figures.learning_curves(rec, summary.get("targets", [])))
    if rec is not None and len(rec.transitions):
        png, counts = figures.world_model(rec)
        ctx["model"] = {"png": _b64(png), "counts": counts}
    genome = summary.get("best_genome")
    if genome:
        reflex = bool((summary.get("config") or {}).get("reflex", True))
        visited = np.unique(rec.state[rec.state != 255]) if rec is not None and rec.has_states else None
        terms = figures.controller_terms(genome)
        ctx["controller"] = {"table": _b64(figures.truth_table(genome, reflex, visited)), "terms": terms,
                             "active": sum(t["outputs"] != "-" and not t["never"] for t in terms)}
    what = "On-line model-based lifetime" if online else "Off-line model-free run"
    ctx["title"] = f"{what}, seed {summary.get('seed')}: {summary.get('targets_reached')} targets"
    return ctx


def _compare_context(run_dir: Path, compare: dict) -> dict:
    methods = compare.get("methods") or {}
    rows = []
    for name, stats in methods.items():
        cells = []
        for key in COMPARE_COLUMNS:
            s = stats.get(key) or {}
            cells.append("-" if s.get("median") is None else
                         f"{_number(s['median'])} [{_number(s.get('min'))}, {_number(s.get('max'))}]")
        rows.append((name, cells))
    paper = compare.get("paper") or {}
    for name, figs in paper.items():
        rows.append((f"paper, {name}", [_number(figs.get(k)) if figs.get(k) is not None else "-"
                                        for k in COMPARE_COLUMNS]))
    try:
        markdown = (run_dir / "compare.md").read_text()
    except OSError:
        markdown = ""
    try:  # cosim.compare.report.write_boxplot's figure, beside compare.json
        box = (run_dir / "compare_box.png").read_bytes()
    except OSError:
        box = None
    seeds = compare.get("seeds") or []
    return {"title": f"Every method over {len(seeds)} seeds, arena {compare.get('arena')!r}",
            "compare_rows": rows, "compare_columns": [c.replace("_", " ") for c in COMPARE_COLUMNS],
            "compare_seeds": ", ".join(str(s) for s in seeds), "compare_box": _b64(box) if box else None,
            "compare_md": markdown}


def report_context(run_dir: Path, fps: float = DEFAULT_FPS, max_seconds: float = DEFAULT_MAX_SECONDS,
                   progress: bool = True) -> dict:
    """The template's values for the run folder ``run_dir``."""
    run_dir = Path(run_dir)
    compare = _read_json(run_dir / "compare.json")
    summary = _read_json(run_dir / "summary.json")
    if isinstance(compare, dict):
        ctx = _compare_context(run_dir, compare)
    elif isinstance(summary, dict) and "targets_reached" in summary:
        ctx = _lifetime_context(run_dir, summary, fps, max_seconds, progress)
    else:
        raise ReportError(f"{str(run_dir)!r} holds no run: no summary.json of `ehw sim` or `ehw offline`, "
                          "no compare.json of `ehw compare`")
    ctx["figures"] = [(name, _b64((run_dir / name).read_bytes())) for name in RUN_FIGURES
                      if (run_dir / name).is_file()]
    sessions = _read_json(run_dir / "sessions.json")
    ctx["sessions"] = [f"{s.get('started')}  {s.get('command')}" for s in sessions or [] if isinstance(s, dict)]
    ctx["command"] = _command(run_dir)
    try:
        ctx["config_text"] = (run_dir / "config.toml").read_text()
    except OSError:
        ctx["config_text"] = ""
    ctx["run_dir"] = str(run_dir.resolve())
    ctx["written"] = _dt.datetime.now().isoformat(timespec="seconds")
    names = {"summary": "summary", "video": "replay", "curves": "learning curves", "model": "world model",
             "controller": "controller", "compare_rows": "every method", "figures": "figures"}
    anchors = {"video": "replay", "compare_rows": "compare"}
    ctx["sections"] = [(anchors.get(k, k), v) for k, v in names.items()
                       if ctx.get(k if k != "summary" else "summary_rows")] + [("config", "configuration")]
    return ctx


def render(ctx: dict) -> str:
    import jinja2

    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATE.parent), autoescape=True)
    return env.get_template(TEMPLATE.name).render(**ctx)


def write_report(run_dir: Path, fps: float = DEFAULT_FPS, max_seconds: float = DEFAULT_MAX_SECONDS,
                 progress: bool = True) -> Path:
    """Write ``run_dir/report.html`` (atomically) and return its path."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise ReportError(f"no run folder {str(run_dir)!r}")
    html = render(report_context(run_dir, fps, max_seconds, progress))
    return atomic_write_text(run_dir / REPORT, html)
