"""More demonstrations: a model (paper setting, speed scale "change") trained on the paper
split's 650 training scenes plus ``EXTRA`` more scenes of the same draw (data seed 0; scenes
890 on), tuned on its 40 and driven on its 200 validation scenes under both protocols.

Run: ``python benchmarks/data_scale.py cnn 1950 6`` (model, extra scenes, epochs); prints the
training and tuning loss per epoch and the closed-loop scores.
"""

import sys
import time

import numpy as np
from scoring import scores

from minimanc import models, rollout, train, world

t0 = time.perf_counter()
name, n_extra, epochs = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
ds = world.generate(890 + n_extra, seed=0, cache=True, progress=False)
print(f"[{time.perf_counter()-t0:.0f}s] data {890 + n_extra}", flush=True)
tr = ds.subset(np.r_[np.arange(650), np.arange(890, 890 + n_extra)])
val = ds.subset(slice(690, 890))
cfg = models.ModelConfig(setting="paper")
tc = train.TrainConfig(epochs=epochs, lr=1e-3, seed=0, speed_scale="change")
res = train.fit(name, tr, cfg, tc, val_ds=ds.subset(slice(650, 690)), progress=False)
print(name, "train", " ".join(f"{v:.2f}" for v in res.history), flush=True)
print(name, "tune ", " ".join(f"{v:.2f}" for v in res.val_history), flush=True)
for a in ("replay", "reactive"):
    traj = rollout.closed_loop(name, res.params, val, cfg, progress=False, agents=a)
    s = scores(traj, val)
    print(f"[{time.perf_counter() - t0:.0f}s] {name} {len(tr.ego)} scenes {a}: at fault "
          f"{s['at_fault_collision_rate']:.1f} % coll {s['collision_rate']:.1f} ADE "
          f"{s['ade']:.2f} off road {s['off_road_rate']:.1f}", flush=True)
