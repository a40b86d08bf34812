"""One-off: convert the shipped policy from stable-baselines3's pickled format to the safe
policy folder format, and prove that it acts identically.

The pickled policy (``model.zip`` + ``vecnormalize.pkl``) and the code that loaded it are
taken from git revision ``--rev`` (the last one that shipped them); the pickles are read
here, once, on purpose.  Both controllers are driven by the same observation sequences (the
old controller closes the loop on hold episodes in front and side wind; the new one is fed
the same observations), and the largest action difference is printed.

    python scripts/convert_shipped_policy.py --rev 6be8de6 --out agents/policies/residual_pi
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import gymnasium as gym
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
POLICY = "agents/policies/residual_pi"


def _git_show(rev: str, path: str) -> bytes:
    return subprocess.run(["git", "show", f"{rev}:{path}"], cwd=ROOT, check=True,
                          capture_output=True).stdout


def _old_code(rev: str, where: Path) -> None:
    """The old agents package as ``oldagents`` (its imports of itself rewritten)."""
    pkg = where / "oldagents"
    pkg.mkdir()
    for f in ("__init__.py", "ppo.py", "policy.py", "residual.py"):
        text = _git_show(rev, f"agents/{f}").decode()
        (pkg / f).write_text(text.replace("dss14_env.agents.", "oldagents."))
    sys.path.insert(0, str(where))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", required=True, help="git revision holding the pickled policy")
    ap.add_argument("--out", default=None, help="write the converted policy folder here")
    ap.add_argument("--episodes", type=int, default=4, help="episodes per wind direction")
    ap.add_argument("--steps", type=int, default=1500, help="steps per episode")
    args = ap.parse_args()

    import dss14_env  # noqa: F401
    from dss14_env.agents.policy import load_policy
    from dss14_env.agents.storage import convert_sb3_policy

    tmp = Path(tempfile.mkdtemp(prefix="convert-policy-"))
    old_dir = tmp / "old"
    old_dir.mkdir()
    for f in ("model.zip", "vecnormalize.pkl", "config.yaml", "evaluations.npz", "train_summary.json"):
        (old_dir / f).write_bytes(_git_show(args.rev, f"{POLICY}/{f}"))
    _old_code(args.rev, tmp)
    from oldagents.policy import PPOController as OldController  # noqa: E402

    new_dir = convert_sb3_policy(old_dir, tmp / "new", trust_pickle=True, algo="ppo",
                                 run_id="residual_pi")
    for f in ("evaluations.npz", "train_summary.json"):
        shutil.copy(old_dir / f, new_dir / f)

    worst, n_obs = 0.0, 0
    for direction in ("front", "side"):
        env = gym.make("DSS14-Hold-v0", wind_direction=direction)
        old = OldController(old_dir, env=env)
        new = load_policy(new_dir, env=env)
        for seed in range(args.episodes):
            obs, _ = env.reset(seed=seed)
            old.reset(seed)
            new.reset(seed)
            for _ in range(args.steps):
                a_old = old.act(obs)
                a_new = new.act(obs)
                worst = max(worst, float(np.max(np.abs(a_old - a_new))))
                n_obs += 1
                obs, *_ = env.step(a_old)
    print(f"{n_obs} observations: largest |action difference| old vs converted = {worst:.3e}"
          f" ({'bitwise identical' if worst == 0.0 else 'differs'})")
    if args.out:
        out = Path(args.out)
        for f in ("model.zip", "vecnormalize.pkl"):
            (out / f).unlink(missing_ok=True)
        for f in new_dir.iterdir():
            shutil.copy(f, out / f.name)
        print(f"converted policy written to {out}")
    return 0 if worst <= 1e-7 else 1


if __name__ == "__main__":
    sys.exit(main())
