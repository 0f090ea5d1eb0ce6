"""What an on-line lifetime (``cosim.online.run.OnlineRun``) leaves for a person to look at: its
figures (``summary.json``), the table beside the paper's (section 5.2) and the plots of Fig. 9-11."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from base.files import atomic_savefig, atomic_write_json
from cosim.paper import PAPER_ONLINE
from ga.genome import hex_from_rows
from sim_world.recording import trajectory_arrays, write_recording


def summary(run) -> dict:
    """The figures of an on-line lifetime (``cosim.online.run.OnlineRun``): the off-line summary's keys
    plus the on-line ones (phases and their reasons), written to ``summary.json``."""
    from cosim.boards.hardware_time import hardware_figures  # EHW time at the FPGA clock (issue 7)

    cfg = run.config
    reasons = Counter(p["reason"] for p in run.phases)
    at64 = next((t for t in run.target_log if t["target"] == min(64, cfg.n_targets)), None)
    out = {
        "method": "online-model-based", "backend": run.backend, "seed": cfg.seed, "arena": cfg.arena,
        "interactions": run.interactions, "generations": run.generations,
        "genetic_operations": run.genetic_operations, "world_states": run.mirror.n_states,
        # As the off-line summary: transitions = distinct (state, motion) pairs met (the
        # world model's entries); transition_outcomes = distinct (s, a, s2, crashed) seen.
        "transitions": run.mirror.n_transitions, "transition_outcomes": len(run.transitions),
        "targets_reached": run.targets,
        "best_genome": None if run.best_rows is None else hex_from_rows(run.best_rows),
        "wall_time_s": round(run.wall_time_s, 3),
        "learning_phases": len(run.phases),
        "phase_reasons": dict(sorted(reasons.items())),
        "interactions_lost_to_timeouts": sum(p["leg_steps"] for p in run.phases
                                             if p["reason"] in ("timeout", "loop")),
        "known_crash_repeats": run.known_crash_repeats,
        "crashes": reasons.get("crash", 0),
        "where_interactions_go": interaction_breakdown(run.phases, run.target_log, run.interactions),
        "board_cycles": {"controller": int(getattr(run.controller, "cycles", 0)),
                         "evaluator": int(getattr(run.evaluator, "cycles", 0))},
        "learnt_from": learnt_from(cfg),
        "config": cfg.to_dict(), "phases": run.phases, "targets": run.target_log,
    }
    if at64 is not None and cfg.n_targets > 64:
        out["at_64_targets"] = at64
    if run.blinded_at is not None:
        out["adaptation"] = adaptation_figures(run.target_log, cfg.blind_after_target, run.blinded_at)
    out["hardware"] = hardware_figures(run)
    return out


def learnt_from(cfg) -> dict:
    """The signals the lifetime learnt from (SPEC section 4, issue 36): the sensor bits, the
    bumper, the target event and the camera's range estimate; the exact distance only for figures."""
    from sim_world.world import CAMERA_RANGE_STEP_MM

    noise = cfg.world_noise()
    return {"state": "8 sensor bits", "events": ["bumper", "target reached"],
            "progress": "camera range", "range_sd": 0.0 if noise is None else noise.range_sd,
            "range_step_mm": CAMERA_RANGE_STEP_MM, "exact_distance": "figures only"}


def interaction_breakdown(phases: list[dict], target_log: list[dict], interactions: int,
                          block: int = 16) -> dict:
    """Where a lifetime's interactions went (docs/research-log.md, on-line round 6).

    - ``in_failed_segments``: the steps from the later of the last target and the last failure
      up to each failure (crash or stop), i.e. what the failures cost; ``per_failure`` its mean;
    - ``first_leg``: the interactions to the first target (from the random start);
    - ``per_block``: the interactions for each ``block`` targets (1-16, 17-32, ...; after
      the last target, one more entry up to the end of the lifetime);
    - ``repeated_blames``: time-outs and loop stops blamed on a (state, motion) already blamed
      for one earlier in the lifetime.
    """
    at = [t["interactions"] for t in target_log]
    lost, last = 0, 0
    for p in phases:
        i = p["interactions"]
        reached = [t for t in at if t <= i]
        lost += i - max(last, reached[-1] if reached else 0)
        last = i
    blamed, repeated = set(), 0
    for p in phases:
        if p["reason"] in ("timeout", "loop"):
            pair = (p["state"], p["motion"])
            repeated += pair in blamed
            blamed.add(pair)
    ends = at + ([interactions] if not at or at[-1] < interactions else [])
    per_block = [ends[min(k + block, len(ends)) - 1] - (ends[k - 1] if k else 0)
                 for k in range(0, len(ends), block)]
    return {"in_failed_segments": lost, "per_failure": round(lost / len(phases), 2) if phases else 0.0,
            "first_leg": at[0] if at else interactions, "per_block": per_block, "block": block,
            "repeated_blames": repeated}


def adaptation_figures(target_log: list[dict], after: int, blinded_at: int, window: int = 8) -> dict:
    """Interactions from the blinding to each of the next ``window`` targets."""
    later = [t for t in target_log if after < t["target"] <= after + window]
    return {
        "blinded_after_target": after,
        "blinded_at_interaction": blinded_at,
        "targets_after": len(later),
        "interactions_for_next_targets": (later[-1]["interactions"] - blinded_at) if len(later) == window else None,
        "per_target": [t["interactions"] - blinded_at for t in later],
    }


def summary_table(summary: dict) -> str:
    """The figures beside the paper's (section 5.2)."""
    rows = [("targets reached", "targets_reached"), ("interactions", "interactions"),
            ("generations", "generations"), ("genetic operations", "genetic_operations"),
            ("world states", "world_states"), ("transitions", "transitions")]
    at64 = summary.get("at_64_targets")
    lines = [f"{'':22s}{'this run':>14s}{'paper':>12s}", "-" * 48]
    for label, key in rows:
        value = summary[key]
        if at64 is not None:  # the figures at the 64th target; the continued run follows below
            value = {"targets_reached": at64["target"],
                     "genetic_operations": at64["generations"] * summary["config"]["population"]
                     }.get(key, at64.get(key))
        lines.append(f"{label:22s}{value:>14,}{PAPER_ONLINE[key]:>12,}")
    lines.append(f"{'learning phases':22s}{summary['learning_phases']:>14,}{'~48':>12s}")
    if at64 is not None:
        lines.append(f"continued to {summary['targets_reached']} targets: {summary['interactions']:,} "
                     f"interactions, {summary['generations']:,} generations (Fig. 11)")
    reasons = ", ".join(f"{k} {v}" for k, v in summary["phase_reasons"].items())
    lines.append(f"phase reasons: {reasons}; wall time {summary['wall_time_s']:.1f} s")
    if "learnt_from" in summary:
        lf = summary["learnt_from"]
        lines.append(f"learnt from: sensor bits, bumper, target event and the {lf['progress']} "
                     f"(error sd {lf['range_sd']:.0%}, {lf['range_step_mm']:g} mm steps); exact distance: figures only")
    if summary["config"].get("distance_rule", "forward") != "forward":
        lines.append(f"fitness distance term: dist[a] = {summary['config']['distance_rule']} "
                     "(the paper's first reading, not SPEC section 7; docs/research-log.md, on-line round 5)")
    if "adaptation" in summary:
        ad = summary["adaptation"]
        lines.append(f"adaptation: IR bit {summary['config']['blind_bit']} blinded after target "
                     f"{ad['blinded_after_target']}: {ad['interactions_for_next_targets']} interactions "
                     f"for the next 8 targets")
    if summary.get("hardware"):
        from cosim.boards.hardware_time import hardware_line

        lines.append(hardware_line(summary))
    return "\n".join(lines)


def write_plots(run, out: Path) -> list[Path]:
    """Fig. 9 (trajectory), Fig. 10 (targets vs generations, states/transitions vs interactions),
    Fig. 11 when the run went past 64 targets."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sim_world.render import plot_trajectory

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    title = (f"On-line model-based lifetime (seed {run.config.seed}): {run.targets} targets, "
             f"{run.interactions:,} interactions")
    path = out / "fig9_trajectory.png"
    plot_trajectory(run.world.arena, [(x, y, h, event) for x, y, h, _state, event in run.trajectory], path,
                    title=title)
    paths.append(path)

    def fig10(limit: int | None, name: str, title: str):
        log = [t for t in run.target_log if limit is None or t["target"] <= limit]
        n = log[-1]["interactions"] if (limit is not None and log) else run.interactions
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.5))
        gens = [0] + [t["generations"] for t in log]
        a1.step(gens, list(range(len(log) + 1)), where="post")
        a1.set_xlabel("generations")
        a1.set_ylabel("targets reached")
        a1.grid(alpha=0.3)
        x = np.arange(1, n + 1)
        a2.plot(x, run.curve_states[:n], label="world states")
        a2.plot(x, run.curve_transitions[:n], label="transitions")
        for t in log:
            a2.axvline(t["interactions"], color="0.85", lw=0.5, zorder=0)
        if limit is None and run.config.n_targets > 64:
            t64 = next((t for t in log if t["target"] == 64), None)
            if t64:
                a1.axvline(t64["generations"], color="r", ls="--", lw=1)
                a2.axvline(t64["interactions"], color="r", ls="--", lw=1, label="64th target")
        a2.set_xlabel("interactions (grey: a target reached)")
        a2.legend()
        a2.grid(alpha=0.3)
        fig.suptitle(title)
        paths.append(out / name)
        atomic_savefig(fig, paths[-1], dpi=110, bbox_inches="tight")
        plt.close(fig)

    fig10(64, "fig10_targets_states.png", "Targets vs generations; states and transitions vs interactions")
    if run.config.n_targets > 64:
        fig10(None, "fig11_continued.png", f"Continued past 64 targets ({run.targets} targets)")
    return paths


def recording_of(run) -> dict:
    """The arrays of ``sim_world.recording`` for an on-line lifetime (``cosim.online.run.OnlineRun``)."""
    phases = run.phases
    transitions = np.array(sorted(run.transitions), dtype=np.uint8).reshape(-1, 4)
    return {
        **trajectory_arrays(run.trajectory),
        "motions": np.asarray(run.motions, dtype=np.uint8),
        "curve_states": np.asarray(run.curve_states, dtype=np.int32),
        "curve_transitions": np.asarray(run.curve_transitions, dtype=np.int32),
        "phase_interaction": np.array([p["interactions"] for p in phases], dtype=np.int32),
        "phase_reason": np.array([p["reason"] for p in phases], dtype="U8"),
        "phase_changed": np.array([bool(p.get("changed", False)) for p in phases], dtype=bool),
        "transitions": transitions,
        "arena": np.array(str(run.config.arena)), "seed": np.array(int(run.config.seed)),
        "method": np.array("online-model-based"),
    }


def write_results(run, out: Path, plots: bool = True) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    summary = run.summary()
    atomic_write_json(out / "summary.json", summary)
    write_recording(recording_of(run), out)  # what `ehw replay` draws
    if plots:
        summary["plots"] = [str(p) for p in write_plots(run, out)]
    return summary
