"""The noisy stage inside one off-line run (`cosim.offline.run.run_offline`): a generation of it,
its final race, its end and its summary (the noisy world, the races and the records:
`cosim.offline.noisy`)."""

from __future__ import annotations

import numpy as np

from cosim.offline.noisy import NoisyStage, Records, final_race, noisy_generation, table_key
from ga.genome import hex_from_rows, rows_from_hex


def fresh_stage_state() -> dict:
    """The noisy stage's part of a run's checkpoint state."""
    return {"records": {}, "from_generation": None, "interactions": 0, "noise_free_best": None,
            "accepted": False, "elites": [], "final_race": None}


def best_entry(rows, ev, **extra) -> dict:
    """The checkpoint's record of a best controller (``ev``: its noise-free `Evaluation`)."""
    return {"genome": hex_from_rows(rows), "fitness": ev.fitness, "targets_reached": ev.targets_reached,
            "steps": ev.steps, "crashed": ev.crashed, "timed_out": ev.timed_out,
            "final_distance_mm": ev.final_distance_mm, **extra}


def stage_step(ga, pop, evaluator, stage: NoisyStage, records: Records, state, seed, arena, max_leg_steps,
               n_targets, states, transitions):
    """One generation of the noisy stage: every individual on the generation's K common noise seeds
    (at ``stage.leg_steps``, else ``max_leg_steps``), fitness = its mean over them. The best is also
    driven once noise-free at ``max_leg_steps`` (``evaluator``, counted, for the summary and the
    history); with ``stage.keep_noise_free`` a challenger must reach every target there to become
    the elite (the gate's run is that same run, counted once).
    Returns the noise-free Evaluation of the best and the history entry's noisy fields."""
    driven = evaluator.simulated_steps
    gated = {}

    def noise_free(rows):
        ev = gated[table_key(rows)] = evaluator(rows[None, :])[0]
        return ev.targets_reached >= n_targets, ev.steps

    keys, runs, fitness, failures, steps, simulated = noisy_generation(
        evaluator.map, pop, stage, records, seed, ga.generation, arena, stage.leg_steps or max_leg_steps,
        n_targets, gate=noise_free if stage.keep_noise_free else None)
    fitness = np.array(fitness, dtype=float)
    ga.tell(fitness, failures=failures)
    i = int(np.argmax(fitness))
    for rs in runs:
        for r in rs:
            states |= r.states
            transitions |= r.transitions
    steps += sum(ev.steps for ev in gated.values())
    best = gated.get(keys[i])
    if best is None:
        best = evaluator(pop[i:i + 1])[0]  # noise-free (cached by truth table)
        steps += best.steps
    for ev in (best, *gated.values()):
        states |= ev.states
        transitions |= ev.transitions
    state["interactions"] += steps
    state["noisy"]["interactions"] += steps
    state["simulated_interactions"] += simulated + evaluator.simulated_steps - driven
    record = records.summary(keys[i])
    state["best"] = best_entry(pop[i], best, noisy_fitness=float(fitness[i]), **record)
    if records.accepted(keys[i], stage.accept_runs):
        state["noisy"]["accepted"] = True
    elites = state["noisy"].setdefault("elites", [])
    if stage.final_race and (not elites or elites[-1][0] != keys[i]):  # the final race's candidates
        elites.append([keys[i], hex_from_rows(pop[i])])
        del elites[:-stage.final_candidates]
    return best, {"stage": 2, "best_noisy_fitness": float(fitness[i]), **record,
                  "clean_runs": sum(r.clean for rs in runs for r in rs)}


def final_step(evaluator, stage: NoisyStage, state, seed, arena, max_leg_steps, n_targets) -> None:
    """The noisy stage's final race (round 5): the last distinct elites on common seeds; the winner
    becomes the result (counted; the winner is also driven once noise-free, for the summary)."""
    candidates = [g for _, g in state["noisy"].get("elites", [])]
    if not candidates:
        return
    winner, table, steps = final_race(evaluator.map, candidates, stage, seed, arena,
                                      stage.leg_steps or max_leg_steps, n_targets)
    rows = rows_from_hex(candidates[winner])
    driven = evaluator.simulated_steps
    best = evaluator(rows[None, :])[0]
    steps += best.steps
    state["interactions"] += steps
    state["noisy"]["interactions"] += steps
    state["simulated_interactions"] += steps - best.steps + evaluator.simulated_steps - driven
    record = Records(state["noisy"]["records"]).summary(table_key(rows))
    state["best"] = best_entry(rows, best, **record)
    state["noisy"]["final_race"] = {"candidates": len(candidates), "winner": winner, "interactions": steps,
                                    "failed_legs_clean_runs_mean_fitness": table}


def stage_over(stage: NoisyStage, noisy_state: dict, generation: int) -> bool:
    """The stage's end: a controller accepted, its generation cap, or its budget (``budget``, or
    ``budget_factor`` x the noise-free stage's interactions)."""
    first = noisy_state["from_generation"]
    if noisy_state["accepted"]:
        return True
    if first is None:
        return False
    spent = noisy_state["interactions"]
    before = (noisy_state["noise_free_best"] or {}).get("interactions", 0)
    return (generation - first + 1 >= stage.max_generations or 0 < stage.budget <= spent
            or (stage.budget_factor > 0 and before > 0 and spent >= stage.budget_factor * before))


def stage_summary(state, generations: int) -> dict:
    """What the noisy stage did: from which generation, its interactions (in ``interactions``
    already), whether a controller was accepted, the final best's record, the noise-free best."""
    noisy, best = state["noisy"], state["best"] or {}
    first = noisy["from_generation"]
    return {"from_generation": first, "generations": 0 if first is None else generations - first + 1,
            "interactions": noisy["interactions"], "accepted": noisy["accepted"],
            "controllers_recorded": len(noisy["records"]),
            **({"final_race": noisy["final_race"]} if noisy.get("final_race") else {}),
            **{k: best[k] for k in ("noisy_runs", "noisy_clean_runs", "noisy_mean_clean_legs") if k in best},
            "noise_free_best": noisy["noise_free_best"]}
