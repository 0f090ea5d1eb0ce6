"""The off-line experiment's figures (paper Fig. 5 and 6) and its table over several seeds."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from base.files import atomic_savefig
from cosim.offline.noisy import load_arena_arg
from cosim.paper import PAPER_OFFLINE as PAPER
from ga.genome import rows_from_hex
from ga.truth_table import truth_tables
from sim_world.course import run_course

# -- Figures -------------------------------------------------------------------------------------


def plot_results(out: Path, history: list, genome_hex: str | None, arena: str, max_leg_steps: int,
                 n_targets: int, seed: int = 0) -> dict:
    """Fig. 5 (the best controller's path through the 64 legs) and Fig. 6 (steps and fitness of
    the best individual per generation), and that path as ``lifetime.npz`` (what ``ehw replay``
    draws; ``sim_world.recording``). Returns the file names written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = {}
    if history:
        gens = [h["generation"] for h in history]
        fig, ax1 = plt.subplots(figsize=(7, 4))
        ax1.plot(gens, [h["best_steps"] for h in history], color="tab:blue", label="steps of the best")
        ax1.set_xlabel("generation")
        ax1.set_ylabel("steps (interactions) of the best", color="tab:blue")
        ax2 = ax1.twinx()
        ax2.plot(gens, [h["best_fitness"] for h in history], color="tab:red", label="fitness of the best")
        ax2.set_ylabel("fitness of the best (targets + R2 + R3)", color="tab:red")
        ax1.set_title("Model-free evolution: the best individual per generation (cf. paper Fig. 6)")
        fig.tight_layout()
        atomic_savefig(fig, out / "fig6_best_per_generation.png", dpi=120)
        plt.close(fig)
        files["fig6"] = "fig6_best_per_generation.png"
    if genome_hex is not None:
        from sim_world.world import World

        world = World(load_arena_arg(arena))
        table = truth_tables(rows_from_hex(genome_hex), reflex=True)
        res = run_course(world, table, max_leg_steps, n_targets=n_targets, record=True)
        title = (f"Best model-free controller: {res.targets_reached} targets, {res.steps} steps "
                 "(cf. paper Fig. 5)")
        path = out / "fig5_trajectory.png"
        from sim_world.render import plot_trajectory

        plot_trajectory(world.arena, res.trajectory, path, title=title)
        files["fig5"] = path.name
        from sim_world.recording import trajectory_arrays, write_recording

        files["recording"] = write_recording({
            **trajectory_arrays(res.trajectory), "arena": np.array(str(arena)), "seed": np.array(int(seed)),
            "method": np.array("offline-model-free")}, out).name
    return files


# -- Several seeds: the table beside the paper's row ---------------------------------------------

TABLE_KEYS = ("generations", "interactions", "world_states", "transitions", "genetic_operations")


def _reach(summary: dict) -> str:
    t = summary.get("transfer", {}).get("targets_without_crash", [])
    return f"{sum(x >= summary['config']['n_targets'] for x in t)}/{len(t)}" if t else "-"


def seeds_table(summaries: list[dict]) -> str:
    """A Markdown table: one row per run, then median [min, max], then the paper's row. The last
    two columns are the transfer's: runs of the final controller reaching every target without a
    crash or a time-out, and the targets before the first crash."""
    head = ["seed", "reached 64", *TABLE_KEYS, "wall time (s)", "noisy world: reach 64",
            "noisy world: targets before a crash"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for s in summaries:
        t = s.get("transfer", {}).get("targets_without_crash", [])
        lines.append("| " + " | ".join([str(s["seed"]), "yes" if s["reached_all_targets"] else
                                        f"no ({s['targets_reached']})", *(f"{s[k]:,}" for k in TABLE_KEYS),
                                        f"{s['wall_time_s']:.0f}", _reach(s),
                                        f"median {np.median(t):g} of {len(t)}" if t else "-"]) + " |")
    if summaries:
        cells = []
        for k in TABLE_KEYS:
            v = [s[k] for s in summaries]
            cells.append(f"{np.median(v):,.0f} [{min(v):,}, {max(v):,}]")
        wall = [s["wall_time_s"] for s in summaries]
        t = [x for s in summaries for x in s.get("transfer", {}).get("targets_without_crash", [])]
        fractions = [s["transfer"]["all_targets_fraction"] for s in summaries if s.get("transfer")]
        reached = sum(s["reached_all_targets"] for s in summaries)
        lines.append("| " + " | ".join([f"median [range] of {len(summaries)}", f"{reached}/{len(summaries)}",
                                        *cells, f"{np.median(wall):.0f} [{min(wall):.0f}, {max(wall):.0f}]",
                                        f"median {np.median(fractions):.0%} [{min(fractions):.0%}, "
                                        f"{max(fractions):.0%}]" if fractions else "-",
                                        f"median {np.median(t):g} [{min(t)}, {max(t)}]" if t else "-"]) + " |")
    lines.append("| " + " | ".join(["paper", "yes", *(f"{PAPER[k]:,}" for k in TABLE_KEYS), "-",
                                    "\"works well\"", "-"]) + " |")
    return "\n".join(lines) + "\n"
