"""The same scene and action sequence give a bitwise-identical final state in two separate processes."""
import subprocess
import sys

SCRIPT = r"""
import hashlib, numpy as np
from muble.sim.env import TabletopEnv
from tests.support.scenes import five_object_scene
scene, models = five_object_scene()
env = TabletopEnv(scene, models)
rng = np.random.default_rng(7)
for a in rng.uniform(-1, 1, size=(60, 7)):
    env.step(a)
print(hashlib.sha256(env.snapshot().state.tobytes()).hexdigest())
"""


def test_sim_same_actions_same_state_in_two_processes():
    digests = []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True)
        digests.append(out.stdout.strip().splitlines()[-1])
    assert digests[0] == digests[1]
    assert len(digests[0]) == 64
