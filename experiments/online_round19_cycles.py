"""Research round 19 (issue 36): a screen of the cycle stop, left the tree at tag research/cycle-screen: one-round cycle stops only for cycles of >= P_MIN pairs, or
only after MIN_STEPS steps of the execution phase. Run from the repository root:
``P_MIN=3 python experiments/online_round19_cycles.py 1001 1010`` prints seed, interactions, targets, phases."""
import json, os, sys
from multiprocessing import Pool
import numpy as np

P_MIN = int(os.environ.get("P_MIN", "2"))
MIN_STEPS = int(os.environ.get("MIN_STEPS", "0"))

def patch():
    from cosim.online import failures
    from ga.motions import OBSTACLE_MASK
    def observe(self, track):
        w, now = track.pairs, track.state
        if len(w) < MIN_STEPS:
            return False
        for p in range(P_MIN, 9):
            n = self.k * p
            if n > len(w) or (self.after_approach and n > track.since_closer):
                break
            if w[-p][0] != now:
                continue
            cycle = [w[i] for i in range(-p, 0)]
            states = [s for s, _ in cycle]
            if len(set(states)) < p or not any(s & OBSTACLE_MASK for s in states):
                continue
            if any(w[-p * r + i] != cycle[i] for r in range(2, self.k + 1) for i in range(p)):
                continue
            if self.radius_mm and track.moved(max(-n - 1, -len(track.places))) > self.radius_mm:
                continue
            self.cycle = cycle
            return True
        return False
    failures.Cycles.observe = observe

def one(seed):
    patch()
    from cosim.online.config import OnlineConfig
    from cosim.online.run import make_run
    s = make_run(OnlineConfig(seed=seed)).run().summary()
    return seed, s["interactions"], s["targets_reached"], s["learning_phases"]

if __name__ == "__main__":
    a, b = int(sys.argv[1]), int(sys.argv[2])
    with Pool(int(os.environ.get("JOBS", "2"))) as pool:
        res = pool.map(one, range(a, b + 1))
    for r in res: print(*r, flush=True)
    print("P_MIN", P_MIN, "MIN_STEPS", MIN_STEPS, "median", np.median([r[1] for r in res]), "reached64", sum(r[2] == 64 for r in res))
