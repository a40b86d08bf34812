"""The shipped training configuration files: their paths, names and algorithms.

Read with the schema's plain YAML reader only, without the configuration's fields (which need
the environments' scenarios), so that importing this module is cheap: ``dss14 --help`` lists
the shipped training configurations without importing the environments, the model or its
control library.

>>> "ppo_plain" in shipped_training_configs_by_algo()["ppo"]
True
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from dss14_env.core.schema import read_config, shipped_configs


def shipped_config_path(name: str) -> Path:
    """Path of a configuration file shipped in the ``configs`` package (``ppo.yaml``)."""
    return Path(str(resources.files("dss14_env.configs").joinpath(name)))


def shipped_training_configs() -> list[str]:
    """Names of the shipped training configurations (``ppo``, ``ppo_plain``, ``sac``, ...)."""
    return [n for n in shipped_configs() if n.split("_")[0] in ("ppo", "sac", "recurrent")]


def shipped_training_configs_by_algo() -> dict[str, list[str]]:
    """The shipped training configurations grouped by their ``algo`` key (read from the files)."""
    out: dict[str, list[str]] = {}
    for name in shipped_training_configs():
        algo = read_config(shipped_config_path(f"{name}.yaml"))[0].get("algo")
        out.setdefault(str(algo), []).append(name)
    return out


__all__ = ["shipped_config_path", "shipped_training_configs", "shipped_training_configs_by_algo"]
