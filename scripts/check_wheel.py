"""Check a built wheel: one top-level import package, ``dss14_env``, with the controllers, the
agents, the configs and the shipped policy inside; and that the installed package is the one
imported (not a source tree).

Usage: ``python scripts/check_wheel.py dist/dss14_env-*.whl`` (run outside the source tree).
"""

from __future__ import annotations

import sys
import zipfile
from pathlib import Path


def top_level(wheel: Path) -> set[str]:
    """Top-level names the wheel installs into site-packages (files and folders)."""
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
    return {n.split("/")[0] for n in names if not n.split("/")[0].endswith((".dist-info", ".data"))}


def main(argv: list[str]) -> int:
    wheel = Path(argv[1])
    tops = top_level(wheel)
    print(f"{wheel.name}: top-level {sorted(tops)}")
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
    need = ["dss14_env/baselines/lqg.py", "dss14_env/agents/policy.py", "dss14_env/configs/model.yaml",
            "dss14_env/envs/env.py", "dss14_env/bench/runner.py"]
    missing = [n for n in need if n not in names]
    policy = [n for n in names if n.startswith("dss14_env/agents/policies/")]
    import dss14_env
    where = Path(dss14_env.__file__).resolve()
    print(f"imported from {where}; shipped policy files: {len(policy)}")
    ok = tops == {"dss14_env"} and not missing and policy and "site-packages" in str(where)
    if not ok:
        print(f"FAILED: top-level {sorted(tops)}, missing {missing}, policy files {len(policy)}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
