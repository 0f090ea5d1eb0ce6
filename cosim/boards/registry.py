"""The board backends by name: ``make_boards`` and ``make_learning_boards`` (SPEC section 9).

- ``reference``: NumPy models (``cosim.boards.reference``), fast;
- ``amaranth``: the Amaranth components in Amaranth's simulator (``cosim.boards.amaranth_backend``);
- ``cocotb``: the generated Verilog in Icarus or Verilator, driven from inside a cocotb test
  (``cosim.boards.cocotb_backend``, launched by ``cosim.launch.cocotb_sim``);
- ``serial``: real boards behind the UART host link (``cosim.link.boards``);
- ``uart``: the board top with its UART in Verilator, reached over a simulated serial line by
  the same host code (``cosim.link.simulated``, launched by ``cosim.launch.uart_sim``);
- ``emulated``: the same host code over a Python model of the ehw-system board's protocol, no
  HDL simulator (``cosim.link.emulated``): the fast line for ``--line-faults``.

The same seed gives the same controllers, trajectory and counts in every backend; the HDL
backends also count clock cycles. Backends are named here by module-name strings and imported
only when asked for, so the loops never import a backend and the reference path needs no
Amaranth or cocotb.
"""

from __future__ import annotations

from cosim.boards.interfaces import BackendUnavailable
from cosim.boards.reference import ReferenceControllerBoard, ReferenceEvaluatorBoard, ReferenceLearningBoard
from ga.motions import DEFAULT_DISTANCE_RULE

# The one place a backend is named: name -> (the module that registers its boards with
# ``register_backend``, or None for the reference below; a launcher "module:function" for a backend
# whose boards exist only inside a simulator that must be started first, or None). Adding a backend
# is one line here plus its module.
_BACKENDS = {
    "reference": (None, None),
    "amaranth": ("cosim.boards.amaranth_backend", None),
    "cocotb": ("cosim.boards.cocotb_backend", "cosim.launch.cocotb_sim:launch"),
    "serial": ("cosim.link.boards", None),  # real boards behind the UART host link
    "uart": ("cosim.link.simulated", "cosim.launch.uart_sim:launch"),  # the link top in Verilator
    "emulated": ("cosim.link.emulated", None),  # the host link to a Python model of the ehw-system board
}
BACKENDS = tuple(_BACKENDS)


# name -> factory(reflex: bool, distance_rule: str = DEFAULT_DISTANCE_RULE, **options) ->
# (ControllerBoard, EvaluatorBoard); distance_rule: dist[a] of the evaluator
# (ga.motions.DISTANCE_RULES). The HDL backends register themselves here (``register_backend``)
# so that the loops never import them directly.
_FACTORIES: dict = {}


def register_backend(name: str, factory) -> None:
    """Make ``make_boards(name, ...)`` call ``factory(reflex=..., **options)``."""
    if name not in BACKENDS:
        raise ValueError(f"unknown backend {name!r}; SPEC section 9 names {BACKENDS!r}")
    _FACTORIES[name] = factory


def _reference_factory(reflex: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE, **options):
    if options:
        raise TypeError(f"the reference backend takes only distance_rule, got {sorted(options)!r}")
    return ReferenceControllerBoard(reflex=reflex), ReferenceEvaluatorBoard(reflex=reflex, distance_rule=distance_rule)


register_backend("reference", _reference_factory)


def make_boards(backend: str = "reference", *, reflex: bool = True, **options):
    """A fresh (controller board, evaluator board) pair of the named backend.

    Both boards start empty: no controller loaded, an empty world model.
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS!r}")
    module = _BACKENDS[backend][0]
    if backend not in _FACTORIES and module is not None:
        # The HDL backends register from their own modules; importing them here keeps the
        # reference path free of Amaranth/cocotb imports.
        import importlib

        try:
            importlib.import_module(module)
        except ModuleNotFoundError as error:
            if error.name != module:
                raise
    if backend not in _FACTORIES:
        raise BackendUnavailable(
            f"backend {backend!r} is not available in this checkout yet (no module registers it); "
            f"use --backend reference"
        )
    return _FACTORIES[backend](reflex=reflex, **options)


def launcher(backend: str):
    """The function ``launch(config, args) -> exit status`` that starts ``backend``'s simulator
    and runs the lifetime inside it, or None when the loop can call the boards directly."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS!r}")
    target = _BACKENDS[backend][1]
    if target is None:
        return None
    import importlib

    module, name = target.split(":")
    return getattr(importlib.import_module(module), name)


# modules import this one, not the reverse). cocotb's exists only inside the simulator (launcher),
# and so does uart's (its board pair's module: ``cosim.link.simulated``).
_LEARNING_FACTORIES = {
    "amaranth": "cosim.boards.amaranth_learning:AmaranthLearningBoard",
    "cocotb": "cosim.boards.cocotb_learning:make_cocotb_learning_board",
    "uart": "cosim.link.simulated:make_uart_learning_boards",
    "serial": "cosim.link.learning:make_serial_learning_boards",
}
# The backends whose learning factory gives (controller board, learning board): the learner top
# (``hdl.learner_link.LearnerLinkTop``) holds the controller board beside the engine behind one
# link, so the run makes no board pair of ``make_boards`` (that would ask for an ehw-system board).
_LEARNING_TOPS = ("uart", "serial")
LEARNING_BACKENDS = ("reference", *_LEARNING_FACTORIES)


def make_learning_boards(backend: str, config, seed: int, population, *, controller=None,
                         reflex: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE):
    """(controller board, learning board) of the named backend: the learning board holds
    ``population``, its generators seeded with ``seed`` (32 bits), and an empty world model. On a
    learner top (``_LEARNING_TOPS``) both boards come from the top; elsewhere the learning board
    goes beside ``controller`` (the one of ``make_boards(backend)``)."""
    if backend not in LEARNING_BACKENDS:
        raise BackendUnavailable(
            f"no learning board for backend {backend!r} yet; --ga hardware runs on {LEARNING_BACKENDS!r}")
    if (controller is None) != (backend in _LEARNING_TOPS):
        raise ValueError(f"the {backend} learning board " + ("brings its own controller board" if controller
                         is not None else "goes beside the controller board of make_boards"))
    if backend == "reference":
        return controller, ReferenceLearningBoard(config, seed, population, reflex, distance_rule)
    import importlib

    module, name = _LEARNING_FACTORIES[backend].split(":")
    made = getattr(importlib.import_module(module), name)(config, seed, population, reflex=reflex,
                                                          distance_rule=distance_rule)
    return made if backend in _LEARNING_TOPS else (controller, made)


def learning_top_drives(backend: str) -> bool:
    """Whether the learning board of ``backend`` comes with its own controller board (a learner
    top: the run then makes no ``make_boards`` pair)."""
    return backend in _LEARNING_TOPS
