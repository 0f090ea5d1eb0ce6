"""Hardware time: what the EHW boards would spend at the FPGA clock, beside the software time.

The HDL backends count clock cycles (``cycles`` of the boards, ``hdl.system_top.SystemHost``).
The evaluator's cost is also known exactly without simulating it: a stream of P controllers on a
model of N states takes :func:`stream_cycles` (P, N) cycles (checked against the simulated
``pop_cycles`` by tests/test_backends.py), so the reference backend reports the same hardware time
from its learning phases.

The clock is measured, not assumed (issue 13): the Fmax that nextpnr reported for the FPGA build
of the design the cycles were counted on, read from ``results/fpga.json`` (``make bitstream``).
The cycles are SystemTop's (both boards and the population streamer, double-buffered evaluator),
so the build in question is ``ulx3s-system`` (SystemTop on an ECP5); ``EHW_FPGA_TARGET`` names
another (the two-iCEBreaker boards' evaluator is single-buffered: its cycle count differs, so
their Fmax only bounds the clock). Without a build the clock is the named default, 12 MHz (the
iCEBreaker's oscillator); ``EHW_CLOCK_HZ`` overrides both. Every figure says which it used.
"""

from __future__ import annotations

import json
from pathlib import Path

from base import environ
from ga.genome import N_ROWS

CLOCK_HZ = 12e6  # the named default without an FPGA build: the iCEBreaker's oscillator
CLOCK_DEFAULT_NAME = "named default, the iCEBreaker's 12 MHz oscillator"
FPGA_RESULTS = Path(__file__).resolve().parents[2] / "results" / "fpga.json"  # hdl.fpga writes it
FPGA_TARGET = "ulx3s-system"  # the build of SystemTop, whose cycles the HDL backends count


def measured_clock(target: str | None = None, results: Path | str | None = None) -> tuple[float, str]:
    """(Hz, where it comes from) for hardware times: ``EHW_CLOCK_HZ`` if set, else the measured
    ``fmax_mhz`` of ``target`` (default ``EHW_FPGA_TARGET`` or ulx3s-system) in ``results``
    (default results/fpga.json), else :data:`CLOCK_HZ`, the named default."""
    hz = environ.read("EHW_CLOCK_HZ")
    if hz is not None:
        return hz, "EHW_CLOCK_HZ"
    target = target or environ.read("EHW_FPGA_TARGET") or FPGA_TARGET
    path = Path(results) if results is not None else FPGA_RESULTS
    try:
        entry = json.loads(path.read_text())["targets"][target]
    except (OSError, ValueError, KeyError, TypeError):
        return CLOCK_HZ, f"{CLOCK_DEFAULT_NAME}: no {target} build in {path.name} (make bitstream)"
    try:
        mhz = float(entry["fmax_mhz"])
    except (KeyError, TypeError, ValueError):
        mhz = 0.0
    if not mhz > 0:
        why = "does not fit its part" if entry.get("fits") is False else "has no Fmax"
        return CLOCK_HZ, f"{CLOCK_DEFAULT_NAME}: the {target} build in {path.name} {why}"
    return mhz * 1e6, f"measured Fmax of {target}, {entry.get('part', '?')}, {path.name}"


def clock_hz_default() -> float:
    """The clock for hardware times in Hz (:func:`measured_clock`)."""
    return measured_clock()[0]


def stream_cycles(population: int, n_states: int, p_max: int | None = None) -> int:
    """Cycles (``pop_cycles``, summed over streams of at most ``p_max``) to evaluate ``population``
    controllers on a model of ``n_states`` states: per stream of P, the ``go`` edge, 50 row writes
    of the first controller, then one controller every max(50, N + 2) cycles (the next one's rows
    are written while this one is evaluated, N + 1 cycles), the last one's N + 1 cycles, and the
    edge that raises ``pop_done``: 53 + N + (P - 1) max(50, N + 2). ``p_max``: the streamer's
    population RAM depth (default ``hdl.system_top.P_MAX``)."""
    if population < 0 or n_states < 0:
        raise ValueError(f"population and n_states must be >= 0, got {population!r}, {n_states!r}")
    if p_max is None:
        from hdl.system_top import P_MAX as p_max  # Amaranth only when a run is summarised
    total = 0
    for first in range(0, population, p_max):
        p = min(p_max, population - first)
        total += 3 + N_ROWS + n_states + (p - 1) * max(N_ROWS, n_states + 2)
    return total


def modeled_evaluator_cycles(phases: list[dict], population: int, generations_per_phase: int) -> int:
    """Evaluator cycles of an on-line run from its phase records (|S| is constant in a phase)."""
    return sum(generations_per_phase * stream_cycles(population, int(p["world_states"])) for p in phases)


def hardware_figures(run, clock_hz: float | None = None) -> dict:
    """The ``hardware`` entry of an on-line run's summary (``cosim.online.run.OnlineRun``)."""
    hz, source = measured_clock() if clock_hz is None else (float(clock_hz), "given")
    cfg = run.config
    modeled = modeled_evaluator_cycles(run.phases, cfg.population, cfg.generations_per_phase)
    evaluator, controller = run.evaluator, run.controller
    sample = int(getattr(evaluator, "sample", 0) or 0)
    measured = 0 if sample else int(getattr(evaluator, "cycles", 0))
    simulated = int(getattr(evaluator, "simulated_cycles", measured))
    if measured != modeled:  # a resumed run: the replay re-observes but does not re-evaluate
        measured = 0
    out = {
        "clock_hz": hz,
        "clock_source": source,
        "evaluator_cycles": measured or modeled,
        "evaluator_cycles_source": "simulated" if measured else "model",
        "evaluator_time_s": (measured or modeled) / hz,
        "controllers_evaluated": run.genetic_operations,
    }
    if measured:
        out["evaluator_cycles_model"] = modeled  # equal to the simulated count (the model is exact)
    if sample:  # spot-check mode: the HDL evaluated `sample` controllers of each population
        out["hdl_sample_per_evaluation"] = sample
    if simulated and not measured:
        out["evaluator_cycles_simulated"] = simulated
    ctl = int(getattr(controller, "cycles", 0))
    if ctl:
        out["controller_cycles"] = ctl
        out["controller_time_s"] = ctl / hz
        out["host_link_cycles"] = int(getattr(evaluator, "transfer_cycles", 0))
    software = getattr(evaluator, "reference_time_s", None)
    if software is None:
        software = getattr(evaluator, "time_s", None)
    if software is not None:
        out["reference_evaluator_time_s"] = round(float(software), 6)
    return out


def hardware_line(summary: dict) -> str:
    """One line for the summary table: the evaluator at the FPGA clock beside the software time."""
    hw = summary.get("hardware")
    if not hw:
        return ""
    mhz = hw["clock_hz"] / 1e6
    ref = hw.get("reference_evaluator_time_s")
    source = f" ({hw['clock_source']})" if hw.get("clock_source") else ""
    text = (f"evaluator EHW at {mhz:g} MHz{source}: {hw['evaluator_time_s']:.3f} s "
            f"({hw['evaluator_cycles']:,} cycles, {hw['evaluator_cycles_source']}, "
            f"{hw['controllers_evaluated']:,} controllers)")
    if ref is not None:
        text += f"; reference evaluator (NumPy) CPU time: {ref:.3f} s"
    if "controller_time_s" in hw:
        text += f"; controller EHW {hw['controller_cycles']:,} cycles"
    return text
