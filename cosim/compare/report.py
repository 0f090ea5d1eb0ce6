"""The comparison's report: statistics over the seeds, compare.md and the plot (cosim.compare.run's).

The method names, their display names and the rows of the table are defined here, once.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from base.files import atomic_savefig
from cosim.paper import PAPER_OFFLINE, PAPER_ONLINE

PAPER = {"online": PAPER_ONLINE, "offline": PAPER_OFFLINE}
TABULAR = ("q-learning", "dyna-q", "dyna-q+", "prioritized-sweeping")
DEEP = ("dqn", "ppo")
METHODS = ("online", "offline", "baseline") + TABULAR + DEEP
OPTIONAL = DEEP  # need the [rl] extra; not in the default --methods
DEFAULT_METHODS = tuple(m for m in METHODS if m not in OPTIONAL)
SHAPINGS = ("shaped", "unshaped")
ROWS = ("interactions", "crashes", "targets_reached", "world_states", "transitions", "generations",
        "genetic_operations", "cpu_s")
ADAPT_WINDOW = 8
N_TARGETS = 64
NAMES = {"online": "on-line model-based", "offline": "off-line model-free", "baseline": "reactive baseline",
         "q-learning": "Q-learning", "dyna-q": "Dyna-Q", "dyna-q+": "Dyna-Q+", "prioritized-sweeping": "prioritized sweeping",
         "dqn": "DQN (SB3)", "ppo": "PPO (SB3)"}


def display_name(row: str) -> str:
    """``q-learning/shaped`` -> ``Q-learning, shaped``."""
    method, _, shaping = row.partition("/")
    return NAMES.get(method, method) + (f", {shaping}" if shaping else "")


# -- the report --------------------------------------------------------------------------------


def _stats(values) -> dict:
    """Median, quartiles (numpy's linear interpolation) and range of the values that are not None."""
    values = [v for v in values if v is not None]
    if not values:
        return {"median": None, "q1": None, "q3": None, "min": None, "max": None}
    q1, med, q3 = np.percentile(values, [25, 50, 75])
    return {"median": float(med), "q1": float(q1), "q3": float(q3), "min": min(values), "max": max(values)}


def _fmt(stat: dict) -> str:
    if stat["median"] is None:
        return "-"
    med = stat["median"]
    text = f"{med:,.0f}" if med == int(med) else f"{med:,.1f}"
    if stat["min"] != stat["max"]:
        lo, hi = stat["min"], stat["max"]
        text += f" ({lo:,.0f}-{hi:,.0f})" if float(lo).is_integer() and float(hi).is_integer() and abs(hi) > 9 \
            else f" ({lo:,.1f}-{hi:,.1f})"
    return text


def _fmt_quartiles(stat: dict) -> str:
    if stat.get("q1") is None:
        return "-"
    return f"{stat['q1']:,.0f}-{stat['q3']:,.0f}"


def build_report(results: dict, arena: str, seeds: list[int]) -> dict:
    """``results[row][seed]`` -> the report: per row the statistics over ``seeds``."""
    report = {"arena": arena, "seeds": seeds, "paper": PAPER, "methods": {}, "per_seed": results}
    for row, per_seed in results.items():
        got = [per_seed[s] for s in seeds if s in per_seed]
        stats = {key: _stats([r.get(key) for r in got]) for key in ROWS}
        stats["reached_64"] = sum(1 for r in got if r.get("targets_reached", 0) >= N_TARGETS)
        stats["seeds_run"] = len(got)
        stats["interactions_per_seed"] = {s: per_seed[s].get("interactions") for s in seeds if s in per_seed}
        # where a lifetime was capped short of 64 targets: how far it got
        stats["capped"] = {s: per_seed[s].get("targets_reached") for s in seeds
                           if s in per_seed and per_seed[s].get("targets_reached", 0) < N_TARGETS}
        report["methods"][row] = stats
    on, off = results.get("online", {}), results.get("offline", {})
    ratios = [off[s]["interactions"] / on[s]["interactions"] for s in seeds
              if s in on and s in off and on[s]["interactions"]]
    if ratios:
        med_on = report["methods"]["online"]["interactions"]["median"]
        med_off = report["methods"]["offline"]["interactions"]["median"]
        report["interaction_ratio"] = {"of_medians": med_off / med_on, "per_seed": ratios,
                                       "median_per_seed": float(np.median(ratios))}
    return report


def add_limit(report: dict, limit: dict | None) -> dict:
    """Put the arena's limit (``cosim.compare.limit.course_limit``) into ``report`` and, per
    method, its median interactions as a multiple of it (``median_over_limit``)."""
    report["limit"] = limit
    for stats in report["methods"].values():
        med = stats["interactions"]["median"]
        stats["median_over_limit"] = med / limit["interactions"] if limit and med is not None else None
    return report


def _overlap(seeds, chosen) -> str:
    used = sorted(set(seeds) & set(chosen))
    return f"**reported seeds {_seed_text(used)} were among them**" if used else "none of the reported seeds was"


def seed_provenance(rows, seeds: list[int]) -> list[str]:
    """Per method family in ``rows``: the seeds its settings were chosen on (each family's own
    record of them) and whether the reported ``seeds`` meet them."""
    from cosim.online.config import CHOSEN_ON_SEEDS
    from peers.deep import TUNED as DEEP_TUNED
    from peers.tabular import TUNED, TUNING_SEEDS
    from sim_world.baseline import TUNING_RUNS

    methods = {r.partition("/")[0] for r in rows}
    lines = []
    if "online" in methods:
        lines.append(f"On-line model-based: its defaults were chosen over the rounds of docs/research-log.md and "
                     f"by `ehw tune online` (its GA's and detectors' values) on seeds "
                     f"{_seed_text(list(CHOSEN_ON_SEEDS))} (`cosim.online.config.CHOSEN_ON_SEEDS`); "
                     f"{_overlap(seeds, CHOSEN_ON_SEEDS)}.")
    if "offline" in methods:
        lines.append("Off-line model-free: the paper's GA; the parameters it leaves open (the directed mutation's "
                     "rate, the leg limit) were chosen on a few low seeds (docs/research-log.md, off-line rounds, "
                     "'The paper's method').")
    if "baseline" in methods:
        noise = sorted({s for arena, noise, s in TUNING_RUNS if arena == "default" and noise is not None})
        lines.append(f"Reactive baseline: its table was tuned on every leg of the default arena's noise seeds "
                     f"{_seed_text(noise)} (`sim_world.baseline.TUNING_RUNS`); {_overlap(seeds, noise)}.")
    if methods & set(TABULAR):
        untuned = sorted(display_name(r) for r in rows if r.partition("/")[0] in TABULAR
                         and tuple(r.split("/")) not in TUNED)
        lines.append(f"Tabular peers: hyper-parameters chosen on seeds {_seed_text(list(TUNING_SEEDS))} "
                     f"(`peers.tabular.TUNED`, `ehw tune`); {_overlap(seeds, TUNING_SEEDS)}"
                     + (f"; not tuned, `peers.tabular.DEFAULTS`: {', '.join(untuned)}" if untuned else "") + ".")
    if methods & set(DEEP):
        untuned = sorted(display_name(r) for r in rows if r.partition("/")[0] in DEEP
                         and not DEEP_TUNED.get(tuple(r.split("/"))))
        lines.append(f"DQN and PPO: stable-baselines3's defaults with peers/deep.py's settings; shaped: learning "
                     f"rate, discount and exploration chosen by `ehw tune` on seeds {_seed_text(list(TUNING_SEEDS))}, "
                     f"unshaped: the earlier grid's learning rate on 1001-1003 (`peers.deep.TUNED`); "
                     f"{_overlap(seeds, TUNING_SEEDS)}"
                     + (f"; not tuned: {', '.join(untuned)}" if untuned else "") + ".")
    return lines


BOX_PLOT = "compare_box.png"  # write_boxplot's file beside compare.json (cosim.report.html embeds it)


def write_boxplot(report: dict, path: Path) -> Path | None:
    """Per method (top to bottom in the table's order): the interactions of each seed's lifetime
    and its targets reached, as box plots (the box: the quartiles; the line: the median; the
    whiskers: 1.5 interquartile ranges), as ``path``; None when no row has a lifetime. The
    report (``cosim.report.html``) embeds this file."""
    from sim_world.render import _plt

    per_seed = report.get("per_seed") or {}
    rows = [r for r in _row_order(per_seed) if any(v.get("interactions") is not None for v in per_seed[r].values())]
    if not rows:
        return None
    rows = rows[::-1]  # matplotlib draws the first box at the bottom
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 0.5 * len(rows) + 2), dpi=110)
    inter = [[v["interactions"] for v in per_seed[r].values() if v.get("interactions") is not None] for r in rows]
    targets = [[v.get("targets_reached", len(v.get("target_interactions") or [])) for v in per_seed[r].values()]
               for r in rows]
    names = [display_name(r) for r in rows]
    a1.boxplot(inter, orientation="horizontal", tick_labels=names)
    a1.set_xscale("log")
    a1.set_xlabel("interactions per lifetime (log)")
    a2.boxplot(targets, orientation="horizontal", tick_labels=names)
    a2.tick_params(axis="y", labelleft=False)  # the same rows as on the left
    a2.set_xlabel("targets reached")
    a1.tick_params(axis="y", labelsize=7)
    for ax in (a1, a2):
        ax.grid(alpha=0.3)
    fig.suptitle(f"every method over seeds {_seed_text(report.get('seeds') or [])} (box: quartiles, line: median)",
                 fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, path)
    plt.close(fig)
    return path


def _over_limit(stats: dict) -> str:
    ratio = stats.get("median_over_limit")
    return "-" if ratio is None else f"{ratio:.1f}"


def _row_order(rows) -> list[str]:
    order = {m: i for i, m in enumerate(METHODS)}
    return sorted(rows, key=lambda r: (order.get(r.partition("/")[0], 99), r))


def _seed_text(seeds: list[int]) -> str:
    """Seeds as runs: 1..280, 1001..1005, 1207."""
    runs: list[list[int]] = []
    for seed in sorted(set(seeds)):
        if runs and seed == runs[-1][-1] + 1:
            runs[-1].append(seed)
        else:
            runs.append([seed])
    return ", ".join(f"{r[0]}..{r[-1]}" if len(r) > 1 else str(r[0]) for r in runs)


def markdown(report: dict) -> str:
    rows = _row_order(report["methods"])
    seeds = report["seeds"]
    limit = report.get("limit")
    lines = [f"# Every method on the same task ({report['arena']} arena, seeds {_seed_text(seeds)})", "",
             "| method | reached 64 | interactions to 64: median (range) | quartiles | median / limit | crashes | "
             "world states | transitions | generations | CPU s per lifetime |", "|---|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        st = report["methods"][row]
        cells = [f"{st['reached_64']}/{st['seeds_run']}", _fmt(st["interactions"]),
                 _fmt_quartiles(st["interactions"]), _over_limit(st),
                 _fmt(st["crashes"]), _fmt(st["world_states"]), _fmt(st["transitions"]), _fmt(st["generations"]),
                 _fmt(st["cpu_s"])]
        lines.append(f"| {display_name(row)} | " + " | ".join(cells) + " |")
    if limit:
        lines.append(f"| the limit (omniscient planner, noise-free) | yes | {limit['interactions']:,} | - | 1.0 | 0 | "
                     "- | - | - | - |")
    for name, paper in (("paper, on-line", PAPER["online"]), ("paper, off-line", PAPER["offline"])):
        lines.append(f"| {name} | yes | {paper['interactions']:,} | - | - | - | {paper['world_states']} | "
                     f"{paper['transitions']} | {paper['generations']} | - |")
    fewer = [f"{display_name(r)}: {report['methods'][r]['seeds_run']}" for r in rows
             if report["methods"][r]["seeds_run"] < len(seeds)]
    if fewer:
        lines += ["", "Rows on fewer seeds (the first ones of the range; CPU at hand): " + "; ".join(fewer) + "."]
    capped = {row: st["capped"] for row, st in report["methods"].items() if st["capped"]}
    if capped:
        lines += ["", "Short of 64 targets (an interaction, generation or crash stop; their interactions are "
                  "lower bounds): " + "; ".join(
                      f"{display_name(r)}: " + ", ".join(f"seed {s} at {t}" for s, t in sorted(c.items()))
                      for r, c in ((r, capped[r]) for r in _row_order(capped)))]
    provenance = report.get("seed_provenance")
    if provenance:
        lines += ["", "## Seeds: which chose the settings, which report them", "",
                  f"Reported: seeds {_seed_text(seeds)}."] + [f"- {line}" for line in provenance]
    if report.get("box_plot"):
        lines += ["", f"Box plots per method (interactions, targets reached): `{report['box_plot']}`."]
    lines += ["", "Every motion executed in the noisy world is one interaction (exploration included); the "
              "reflex drives the four obstacle-free states in every method. 'shaped': the reward adds the "
              "progress towards the ball, a distance the 8-bit state does not contain (peers/lifetime.py); "
              "'unshaped': target, crash and step rewards only. Off-line: interactions of every "
              "controller the GA evaluated; its crashes end those evaluations and are not counted. "
              "CPU seconds: the lifetime's worker process."]
    if limit:
        lines += ["", f"The limit: the fewest interactions any controller could need on this course, from an "
                  f"omniscient planner that knows the arena, the ball and the pose exactly and searches the 8 "
                  f"motions for the shortest crash-free path of each leg (noise-free; cell {limit['cell_mm']:g} mm; "
                  "`ehw limit`, docs/limit.md). 'median / limit': each method's median as a multiple of it."]
    if report.get("online_distance_rule", "forward") != "forward":
        lines += ["", f"On-line runs with the option dist[a] = {report['online_distance_rule']} (the "
                  "paper's first reading, not SPEC section 7; docs/research-log.md, on-line round 5)."]
    if report.get("online_options"):
        lines += ["", "On-line options: " + ", ".join(f"`{k}={v}`" for k, v in report["online_options"].items())
                  + " (defaults otherwise)."]
    if "interaction_ratio" in report:
        r = report["interaction_ratio"]
        lines += ["", f"Interaction ratio off-line / on-line: **{r['of_medians']:.0f}** (ratio of the "
                  f"medians; per seed {', '.join(f'{x:.0f}' for x in r['per_seed'])}); paper: 267 "
                  "(3,283,269 / 12,280), 'about 250'."]
    if "adaptation" in report:
        a = report["adaptation"]
        lines += ["", f"## Adaptation: IR bit {a['bit']} blinded after target {a['after']}", "",
                  f"Interactions for the next {ADAPT_WINDOW} targets (per seed; '-' = did not reach them):", "",
                  "| seed | on-line (learning) | fixed off-line controller |", "|---|---|---|"]
        for row in a["per_seed"]:
            on = row["online"] if row["online"] is not None else "-"
            off = row["offline"] if row["offline"] is not None else "-"
            lines.append(f"| {row['seed']} | {on} | {off} |")
    online = report["per_seed"].get("online", {})
    if online:
        lines += ["", "On-line learning phases by reason (per seed): " + "; ".join(
            f"{s}: {v.get('phase_reasons')}" for s, v in sorted(online.items()))]
    if report.get("wall_time_s") is not None:
        lines += ["", f"Wall time of this comparison: {report['wall_time_s']:,.0f} s ({report.get('executor')})."]
    return "\n".join(lines) + "\n"


def _curve(target_interactions: list[int], grid: np.ndarray, end: int) -> np.ndarray:
    """Targets reached after x interactions, for x on ``grid`` (NaN past the lifetime's end
    ``end`` unless it reached them all: then the count holds)."""
    y = np.searchsorted(np.asarray(target_interactions, dtype=float), grid, side="right").astype(float)
    if len(target_interactions) < N_TARGETS:
        y[grid > end] = len(target_interactions)  # capped: stays where it stopped
    return y


def write_plot(report: dict, path: Path) -> Path:
    """Targets reached against interactions: per method the median over the seeds and its range
    (dashed: unshaped rewards; off-line: targets of its best controller so far)."""
    from sim_world.render import _plt

    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 5), dpi=110)
    ends = [r.get("interactions") or 1 for per in report["per_seed"].values() for r in per.values()]
    grid = np.unique(np.geomspace(10, max(max(ends, default=10), 100) * 1.05, 600).round())
    colours = dict(zip(METHODS, plt.get_cmap("tab10").colors))
    for row in _row_order(report["methods"]):
        per = report["per_seed"][row]
        curves = [_curve(r.get("target_interactions") or [], grid, r.get("interactions") or 0)
                  for s, r in per.items() if "target_interactions" in r]
        if not curves:
            continue
        ys = np.vstack(curves)
        colour = colours.get(row.partition("/")[0], "grey")
        style = "--" if row.endswith("/unshaped") else "-"
        ax.fill_between(grid, ys.min(axis=0), ys.max(axis=0), color=colour, alpha=0.12, linewidth=0)
        med = report["methods"][row]["interactions"]["median"]
        ratio = report["methods"][row].get("median_over_limit")
        label = display_name(row) if med is None else f"{display_name(row)} (median {med:,.0f}" + \
            (f", {ratio:.1f}x the limit)" if ratio is not None else ")")
        ax.plot(grid, np.median(ys, axis=0), color=colour, linestyle=style, label=label, linewidth=1.6)
    limit = report.get("limit")
    if limit:  # the planner's targets against its interactions: below it no controller can be
        ax.plot(grid, _curve(np.cumsum(limit["per_leg"]).tolist(), grid, limit["interactions"]), color="tab:red",
                linestyle="-.", linewidth=1.2, label=f"the limit (omniscient planner, {limit['interactions']:,})")
    ax.axvline(PAPER["online"]["interactions"], color="k", linestyle=":", linewidth=1)
    ax.text(PAPER["online"]["interactions"], 1, " paper on-line\n 12,280", fontsize=7, va="bottom")
    ax.set_xscale("log")
    ax.set_ylim(0, N_TARGETS + 1)
    ax.set_xlabel("interactions (motions executed in the noisy world)")
    ax.set_ylabel("targets reached")
    ax.set_title(f"Targets reached against interactions, median and range over seeds "
                 f"{_seed_text(report['seeds'])}", fontsize=9)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, path)
    plt.close(fig)
    return path
