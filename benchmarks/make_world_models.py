"""Regenerate benchmarks/data/world_model_{100,167}.json: the world model of the on-line lifetime
of seed 1 (reference backend, host GA, the default options of commit b9907d9: distance rule
"covered", no loop-cycle detector; the stored models were made then) when it first holds at least 100 and 167
states (the lifetime ends with 167).

    .venv/bin/python -m benchmarks.make_world_models      (about 3 minutes)
"""

from __future__ import annotations

from pathlib import Path

from cosim.online.run import OnlineConfig, make_run

DATA = Path(__file__).resolve().parent / "data"
SIZES = (100, 167)


def main() -> None:
    run = make_run(OnlineConfig(seed=1), "reference")
    want = list(SIZES)
    phases = 0
    while want and run.targets < 64:
        phases += 1
        run.run(stop_after_phases=phases)
        if run.mirror.n_states >= want[0]:
            path = run.mirror.save(DATA / f"world_model_{want.pop(0)}.json")
            print(f"{path}: {run.mirror.n_states} states, phase {phases}, {run.targets} targets, "
                  f"{run.interactions} interactions")
        if len(run.phases) < phases:  # the lifetime ended
            break


if __name__ == "__main__":
    main()
