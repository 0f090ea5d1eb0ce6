"""The report's pictures, each a PNG as bytes (embedded in ``report.html``, never a file):
the learning curves, the world model, the evolved controller's truth table, the comparison's box
plot; and the controller's 50 terms as text."""

from __future__ import annotations

import io

import numpy as np

from sim_world.recording import Recording
from ga.genome import LITERAL_BITS, N_ROWS, OUTPUT_SHIFT, rows_from_hex
from ga.motions import N_INPUTS, N_MOTIONS, N_OUTPUTS, N_STATES, Motion
from ga.truth_table import truth_tables


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _png(fig) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100, bbox_inches="tight")
    _plt().close(fig)
    return buffer.getvalue()


def learning_curves(rec: Recording, target_log: list[dict]) -> bytes:
    """Targets reached, world states and model transitions against interactions; a tick per
    learning phase."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 3.8))
    at = [t["interactions"] for t in target_log]
    end = int(rec.interaction[-1]) if len(rec.interaction) else 0
    a1.step([0, *at, end], [0, *range(1, len(at) + 1), len(at)], where="post")
    a1.set_xlabel("interactions")
    a1.set_ylabel("targets reached")
    a1.grid(alpha=0.3)
    x = np.arange(1, len(rec.curve_states) + 1)
    a2.plot(x, rec.curve_states, label="world states |S|")
    a2.plot(x, rec.curve_transitions, label="transitions (model entries)")
    for k in rec.phase_interaction:
        a2.axvline(int(k), color="0.88", lw=0.5, zorder=0)
    a2.set_xlabel("interactions (grey: a learning phase)")
    a2.legend(loc="lower right", fontsize=8)
    a2.grid(alpha=0.3)
    return _png(fig)


def world_model(rec: Recording) -> tuple[bytes, dict]:
    """The world model learnt: per (state, motion) whether it is unknown, observed or a crash,
    for the states met (rows), with the counts."""
    plt = _plt()
    from matplotlib.colors import ListedColormap

    t = rec.transitions.astype(np.int64)
    grid = np.zeros((N_STATES, N_MOTIONS), dtype=np.int8)
    if len(t):
        grid[t[:, 0], t[:, 1]] = np.maximum(grid[t[:, 0], t[:, 1]], 1)
        crash = t[t[:, 3] == 1]
        grid[crash[:, 0], crash[:, 1]] = 2
    met = np.unique(np.concatenate([t[:, 0], t[:, 2]])) if len(t) else np.zeros(0, np.int64)
    rows = grid[met] if len(met) else np.zeros((1, N_MOTIONS), np.int8)
    fig, ax = plt.subplots(figsize=(11, 3.4))
    ax.imshow(rows.T, aspect="auto", interpolation="nearest", vmin=0, vmax=2,
              cmap=ListedColormap(["#f2f2f2", "#4c9be8", "#d62728"]))
    ax.set_yticks(range(N_MOTIONS), [m.name.lower().replace("_", " ") for m in Motion], fontsize=7)
    step = max(1, len(met) // 24)
    ax.set_xticks(range(0, len(met), step), [f"{int(s):08b}" for s in met[::step]], rotation=90, fontsize=6)
    ax.set_xlabel("world states met (x7..x0), in order")
    ax.set_title("world model: grey unknown, blue an observed transition, red a crash", fontsize=9)
    counts = {"states": int(len(met)), "transitions": int(np.sum(grid > 0)),
              "crash_pairs": int(np.sum(grid == 2)), "outcomes": int(len(t))}
    return _png(fig), counts


def _literal(i: int, negated: bool) -> str:
    return f"¬x{i}" if negated else f"x{i}"


def controller_terms(genome_hex: str) -> list[dict]:
    """The 50 rows of the AND-OR array: the AND of their literals, the outputs they drive
    (SPEC section 3: bit 2i connects x_i, bit 2i + 1 NOT x_i, bit 16 + j output y_j)."""
    rows = rows_from_hex(genome_hex)
    terms = []
    for r, word in enumerate(int(w) for w in rows):
        literals = [_literal(i, bool(b)) for i in range(N_INPUTS) for b in (0, 1) if word >> (2 * i + b) & 1]
        contradiction = any(word >> (2 * i) & 3 == 3 for i in range(N_INPUTS))
        outputs = [f"y{j}" for j in range(N_OUTPUTS) if word >> (OUTPUT_SHIFT + j) & 1]
        terms.append({"row": r, "and": " ∧ ".join(literals) or "1 (no literal)",
                      "outputs": " ".join(outputs) or "-", "never": contradiction,
                      "word": f"{word:0{(LITERAL_BITS + N_OUTPUTS + 3) // 4}x}"})
    assert len(terms) == N_ROWS
    return terms


def truth_table(genome_hex: str, reflex: bool, visited: np.ndarray | None = None) -> bytes:
    """The controller's motion for each of the 256 sensor inputs, as a heat map (motion x state;
    states the robot met are marked under the map)."""
    plt = _plt()
    table = truth_tables(rows_from_hex(genome_hex), reflex=reflex)
    onehot = np.zeros((N_MOTIONS, N_STATES))
    onehot[table.astype(np.int64), np.arange(N_STATES)] = 1
    fig, ax = plt.subplots(figsize=(11, 2.9))
    ax.imshow(onehot, aspect="auto", interpolation="nearest", cmap="Blues", vmin=0, vmax=1)
    if visited is not None and len(visited):
        ax.plot(visited, np.full(len(visited), N_MOTIONS - 0.3), "|", color="tab:red", ms=6, clip_on=False)
    ax.set_yticks(range(N_MOTIONS), [m.name.lower().replace("_", " ") for m in Motion], fontsize=7)
    ax.set_xticks(range(0, N_STATES, 16), [f"{s:08b}" for s in range(0, N_STATES, 16)], rotation=90, fontsize=6)
    ax.set_xlabel("sensor input x7..x0 (x7 x6: the ball's sector; x5..x0: obstacles); red: met in the run")
    ax.set_title("truth table of the evolved controller" + (" (with the reflex)" if reflex else ""), fontsize=9)
    return _png(fig)
