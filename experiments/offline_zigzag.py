"""Round 4 screening (docs/offline.md): the robust stage with a heading bias that changes sign every
K motions (a deterministic zig-zag drift) instead of a constant one.

    python experiments/offline_zigzag.py K -- [ehw offline options]

The robust stage's worlds (`cosim.offline._world`) are replaced by `ZigZagWorld`s: a world of
`Bias(+b, s)` turns +b degrees a motion for K motions, then -b for K, and so on (the phase counts
the world's interactions, reset with each relocation, so a leg's drift does not depend on the legs
before). Everything else is `ehw offline`.
"""

from __future__ import annotations

import math
import sys

import cosim.offline as offline
from cosim.cli import main
from sim_world.world import World


class ZigZagWorld(World):
    period = 5

    def relocate(self, i: int) -> int:
        self._phase = 0
        return super().relocate(i)

    def reset_to_start(self) -> int:
        self._phase = 0
        return super().reset_to_start()

    def step(self, motion: int):
        if self._bias is not None:
            scale, turn = self._bias
            sign = -1.0 if (self._phase // self.period) % 2 else 1.0
            self._bias = (scale, sign * abs(turn) * math.copysign(1.0, self.bias.rotation_deg))
            self._phase += 1
        return super().step(motion)


def _world(arena: str, bias=None):
    world = offline._WORLDS.get((arena, bias))
    if world is None:
        world = offline._WORLDS[arena, bias] = ZigZagWorld(offline._load_arena(arena), bias=bias)
    return world


if __name__ == "__main__":
    ZigZagWorld.period = int(sys.argv[1])
    offline._world = _world
    sys.exit(main(["offline", *sys.argv[3 if sys.argv[2:3] == ["--"] else 2:]]))
