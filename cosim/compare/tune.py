"""Equal-effort tuning (issue 36): every learning method of ``ehw compare`` gets the same search.

    ehw tune METHOD [--shaping shaped] --trials N --seeds 1001-1005 [--jobs 2] [--out results/tune]

* **Search**: Optuna's TPE sampler, seeded (``--sampler-seed``), over the method's knobs
  (:data:`SPACES`: the tabular learners' step size, discount, exploration, planning and bonus;
  DQN's and PPO's learning rate, discount and exploration; the on-line method's GA rates,
  generations per phase, progress weight and failure detectors). The same ``--trials`` and the
  same ``--seeds`` for every method is the equal effort.
* **Objective**: the median over the tuning seeds of the interactions to 64 targets; a lifetime
  that stops at the cap (100,000) short of 64 counts at the cap.
* **Storage**: the study lives in SQLite, ``<out>/<method>[-<shaping>].db``, named by the method
  and its seeds; running the same command again continues it up to ``--trials`` finished trials
  (Optuna's ``load_if_exists``; a trial cut off by an interruption is failed and run again).
  Every lifetime goes through the comparison's cache (``results/compare/cache``, by method,
  config and seed), so an interrupted trial loses only the lifetime in progress, and
  ``ehw compare`` finds the tuned settings' lifetimes there.
* **Output**: ``<out>/<study>.json``: the best settings, their median and per-seed figures, and
  every trial. Apply the best as the method's defaults (``peers.tabular.TUNED``,
  ``peers.deep.TUNED``, ``cosim.online.config.OnlineConfig``) and record the study in docs/peers.md.
"""

from __future__ import annotations

import dataclasses
import json
import statistics
import warnings
from pathlib import Path

from base.errors import UserError
from base.files import atomic_write_text
from cosim.compare.report import DEEP, N_TARGETS, TABULAR

TUNE_ROOT = Path("results/tune")
METHODS = ("online",) + TABULAR + DEEP
CAP = 100_000  # peers.lifetime.MAX_INTERACTIONS, OnlineConfig.max_interactions


def _tabular_space(method: str):
    def space(trial) -> dict:
        params = {"alpha": trial.suggest_float("alpha", 0.05, 1.0),
                  "gamma": trial.suggest_float("gamma", 0.8, 0.99),
                  "epsilon": trial.suggest_float("epsilon", 1e-3, 0.2, log=True),
                  "q_init": trial.suggest_float("q_init", 0.0, 2.0)}
        if method != "q-learning":
            params["planning_steps"] = trial.suggest_int("planning_steps", 1, 50, log=True)
        if method == "dyna-q+":
            params["kappa"] = trial.suggest_float("kappa", 1e-5, 1e-1, log=True)
        return params
    return space


def _dqn_space(trial) -> dict:
    return {"learning_rate": trial.suggest_float("learning_rate", 1e-5, 3e-3, log=True),
            "gamma": trial.suggest_float("gamma", 0.8, 0.99),
            "exploration_fraction": trial.suggest_float("exploration_fraction", 0.01, 0.3, log=True),
            "exploration_final_eps": trial.suggest_float("exploration_final_eps", 1e-3, 0.1, log=True)}


def _ppo_space(trial) -> dict:
    return {"learning_rate": trial.suggest_float("learning_rate", 1e-5, 3e-3, log=True),
            "gamma": trial.suggest_float("gamma", 0.8, 0.99),
            "ent_coef": trial.suggest_float("ent_coef", 1e-4, 0.1, log=True)}


def _online_space(trial) -> dict:
    def rate(name: str, lo: float, hi: float) -> float:
        return trial.suggest_float(name, lo, hi, log=True)

    return {"generations_per_phase": trial.suggest_int("generations_per_phase", 4, 20),
            "literal_rate": rate("literal_rate", 1e-3, 2e-2), "output_rate": rate("output_rate", 1e-3, 2e-2),
            "switch_rate": rate("switch_rate", 2e-3, 5e-2), "replace_rate": rate("replace_rate", 1e-3, 2e-2),
            "progress_weight": trial.suggest_float("progress_weight", 0.0, 6.0),
            "loop_window": trial.suggest_int("loop_window", 40, 200),
            "max_leg_steps": trial.suggest_int("max_leg_steps", 200, 1000),
            "cycles_after_approach": trial.suggest_categorical("cycles_after_approach", [False, True])}


SPACES = {"online": _online_space, **{m: _tabular_space(m) for m in TABULAR}, "dqn": _dqn_space, "ppo": _ppo_space}


def incumbent(method: str, shaping: str) -> dict:
    """The settings ``ehw compare`` runs today, in the space's names: every study's first trial, so a
    study's best is never worse on the tuning seeds than what it replaces."""
    import optuna

    names = SPACES[method](optuna.create_study().ask()).keys()
    if method == "online":
        from cosim.online.config import OnlineConfig

        current = dataclasses.asdict(OnlineConfig())
    elif method in TABULAR:
        from peers.tabular import tuned_config

        current = dataclasses.asdict(tuned_config(method, shaping))
    else:
        from peers.deep import HYPER, TUNED

        current = {**HYPER[method], **TUNED.get((method, shaping), {})}
    return {name: current[name] for name in names}


def study_name(method: str, shaping: str, seeds) -> str:
    """The study's name: method, reward (peers) and tuning seeds (another seed set: another study)."""
    return f"{method}{'' if method == 'online' else '/' + shaping} seeds {','.join(map(str, seeds))}"


def trial_tasks(method: str, shaping: str, params: dict, seeds, arena: str, out: str) -> list[dict]:
    """The comparison's tasks (``cosim.compare.run.make_tasks``) of one trial: ``params`` over the
    method's untuned defaults, one task per seed (so the comparison's cache serves both)."""
    from cosim.compare.run import make_tasks

    if method == "online":
        return make_tasks(["online"], seeds, arena=arena, out=out, online=params)
    tasks = make_tasks([method], seeds, arena=arena, out=out, shapings=(shaping,))
    if method in TABULAR:
        from peers.tabular import DEFAULTS

        key, value = "learner", dataclasses.asdict(dataclasses.replace(DEFAULTS[method], **params))
    else:
        from peers.deep import HYPER

        key, value = "hyper", {**HYPER[method], **params}
    return [{**t, "config": {**t["config"], key: value}} for t in tasks]


def to_64(result: dict) -> int:
    """Interactions to 64 targets; a lifetime short of 64 (stopped at the cap) counts at the cap."""
    at = result.get("target_interactions") or []
    return int(at[N_TARGETS - 1]) if len(at) >= N_TARGETS else CAP


def check_method(method: str) -> None:
    if method not in METHODS:
        raise UserError(f"METHOD must be one of {', '.join(METHODS)}, got {method!r}")
    if method in DEEP:
        import importlib.util

        if importlib.util.find_spec("stable_baselines3") is None:
            raise UserError(f"tuning {method} needs the deep-RL extra: make rl (pip install -e '.[rl]')")


def tune(method: str, seeds, trials: int, *, shaping: str = "shaped", arena: str = "default",
         out: Path = TUNE_ROOT, jobs: int = 1, sampler_seed: int = 0, cache_root: Path | None = None,
         progress: bool = True) -> dict:
    """Run (or continue) the study of ``method`` up to ``trials`` finished trials; its report."""
    import optuna

    from cosim.compare.options import COMPARE_ROOT
    from cosim.compare.run import run_task
    from cosim.compare.sweep import Cache, executor, run_sweep

    check_method(method)
    seeds = [int(s) for s in seeds]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    stem = method if method == "online" else f"{method}-{shaping}"
    with warnings.catch_warnings():  # the heartbeat (a killed run's trial is failed) is "experimental"
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        storage = optuna.storages.RDBStorage(f"sqlite:///{out / stem}.db", heartbeat_interval=30,
                                             grace_period=120)
    name = study_name(method, shaping, seeds)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(study_name=name, storage=storage, direction="minimize", load_if_exists=True,
                                sampler=optuna.samplers.TPESampler(seed=sampler_seed))
    if not study.trials:
        study.enqueue_trial(incumbent(method, shaping), user_attrs={"incumbent": True})
    requeue_failed(study)
    cache = Cache(cache_root or COMPARE_ROOT / "cache")
    lifetimes = str(out / "lifetimes")  # the on-line lifetimes' folders (checkpoints)

    def objective(trial) -> float:
        tasks = trial_tasks(method, shaping, SPACES[method](trial), seeds, arena, lifetimes)
        results = run_sweep(run_task, tasks, pool, cache)
        per_seed = {str(t["seed"]): to_64(r) for t, r in zip(tasks, results)}
        trial.set_user_attr("per_seed", per_seed)
        trial.set_user_attr("targets", {str(t["seed"]): r.get("targets_reached") for t, r in zip(tasks, results)})
        return float(statistics.median(per_seed.values()))

    done = sum(t.state == optuna.trial.TrialState.COMPLETE for t in study.trials)
    if done < trials:
        with executor(jobs) as pool:
            study.optimize(objective, n_trials=trials - done, show_progress_bar=progress, gc_after_trial=False)
    report = study_report(study, method, shaping, seeds, trials, sampler_seed)
    atomic_write_text(out / f"{stem}.json", json.dumps(report, indent=1) + "\n")
    return report


def requeue_failed(study) -> None:
    """Trials an interruption cut off (failed, or running with a stale heartbeat) run again first,
    with the same settings (their finished lifetimes come from the cache), once each."""
    import optuna

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        optuna.storages.fail_stale_trials(study)
    trials = study.trials
    retried = {t.user_attrs.get("retry_of") for t in trials}
    for t in trials:
        if t.state == optuna.trial.TrialState.FAIL and t.number not in retried and "retry_of" not in t.user_attrs:
            study.enqueue_trial(t.params, user_attrs={"retry_of": t.number})


def study_report(study, method: str, shaping: str, seeds, trials: int, sampler_seed: int) -> dict:
    import optuna

    complete = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    best = min(complete, key=lambda t: (t.value, t.number)) if complete else None
    first = next((t for t in complete if t.user_attrs.get("incumbent")), None)
    return {
        "method": method, "shaping": None if method == "online" else shaping, "study": study.study_name,
        "sampler": f"TPE (optuna {optuna.__version__}), seed {sampler_seed}", "tuning_seeds": list(seeds),
        "budget_trials": trials, "finished_trials": len(complete),
        "objective": f"median interactions to {N_TARGETS} targets over the tuning seeds (capped at {CAP:,})",
        "best": None if best is None else {"trial": best.number, "median": best.value, "params": best.params,
                                           "per_seed": best.user_attrs.get("per_seed")},
        "incumbent": None if first is None else {"trial": first.number, "median": first.value,
                                                 "params": first.params, "per_seed": first.user_attrs.get("per_seed")},
        "trials": [{"trial": t.number, "median": t.value, "params": t.params,
                    "per_seed": t.user_attrs.get("per_seed")} for t in complete],
    }


def report_text(report: dict) -> str:
    best = report["best"]
    lines = [f"study {report['study']!r}: {report['finished_trials']} of {report['budget_trials']} trials, "
             f"{report['sampler']}", f"objective: {report['objective']}"]
    if best is None:
        return "\n".join(lines + ["no finished trial"])
    lines.append(f"best: trial {best['trial']}, median {best['median']:,.0f} (per seed {best['per_seed']})")
    lines += [f"  {k} = {v:.6g}" if isinstance(v, float) else f"  {k} = {v}" for k, v in best["params"].items()]
    if report.get("incumbent"):
        lines.append(f"today's settings (trial {report['incumbent']['trial']}): median {report['incumbent']['median']:,.0f}")
    return "\n".join(lines)
