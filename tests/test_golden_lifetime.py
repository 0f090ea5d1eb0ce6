"""The golden lifetime: a short on-line lifetime of today's default, pinned figure by figure.

The research scripts of rounds 6-18 (at the tag ``research/round-18``) used to pin their defaults
against ``make_run``; this one test stands in for them. It runs the default configuration
(``OnlineConfig()`` but for 16 targets) on the reference boards, seed 1 (2-3 CPU s), and
compares its summary figures and a sha256 of every motion it executed with the values below.

The values were first computed with the code of the tag ``research/round-18`` (commit 289673f)
and main after "the house" (issue 35): 723 interactions, 45 phases. Re-pinned for honest sensing
(issue 36): the per-pair progress and the no-progress window learn from the camera's noisy range
estimate (SPEC section 4), no longer the exact distance: 802 interactions, 41 phases; then the
cycle stop by odometry alone (``cycles_after_approach`` False): 873 interactions, 95 phases; then
the values ``ehw tune online`` chose (issue 36: the GA's rates, 8 generations a phase, the leg
time-out 230, the no-progress window 174, progress weight 0.59): 757 interactions, 78 phases.
A change of any of them means the lifetime changed: the method, its defaults, a random stream or
the world. Re-pin them only for an intended change of the method, and say so in the commit
message (what changed and why the lifetime had to).
"""

from __future__ import annotations

import hashlib

from cosim.online.config import OnlineConfig
from cosim.online.run import make_run

GOLDEN_CONFIG = OnlineConfig(seed=1, n_targets=16)
GOLDEN = {
    "interactions": 757,
    "targets_reached": 16,
    "learning_phases": 78,
    "phase_reasons": {"crash": 15, "loop": 63},
    "generations": 624,
    "world_states": 97,
    "transitions": 217,
}
# sha256 of bytes(run.motions), the motions executed in order (the checkpoint's replay log).
GOLDEN_MOTIONS_SHA256 = "efa22668a5a969078ba54511f7a32a61708d23a33c0bc2674c742380f4ec2390"


def test_the_default_lifetime_is_the_golden_one():
    run = make_run(GOLDEN_CONFIG, "reference", None).run()
    summary = run.summary()
    assert {k: summary[k] for k in GOLDEN} == GOLDEN
    assert len(run.motions) == summary["interactions"]
    assert hashlib.sha256(bytes(run.motions)).hexdigest() == GOLDEN_MOTIONS_SHA256
