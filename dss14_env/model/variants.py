"""The drive variants: the plausible ends of the drive/structure compliance split.

[R] Table 4 gives the servo error at the drive encoders.  It cannot tell a soft drive in weak
wind from a stiff drive in strong wind: both give the same encoder error.  The dish's pointing
error can tell them apart, because the structure above the drive deflects in proportion to the
load.  The shipped model (``configs/model.yaml``) takes the drive that fits both anchors best
(Table 4 and the public wind-load evidence, docs/wind.md section 6); the variants are the two
ends of what the evidence leaves open, each a shipped model file built on the nominal one
(``base: model``) with the wind loads refitted to Table 4 on it (``recalibrate_wind: true``).
Use them as ``gym.make(..., model_config="model_soft")`` or through the bench's ``--variants``.

>>> sorted(DRIVE_VARIANTS)
['soft', 'stiff']
>>> DRIVE_VARIANTS["stiff"].config
'model_stiff'
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType


@dataclass(frozen=True)
class DriveVariant:
    """One end of the drive/structure split.

    :param name: short name (the bench's ``--variants``)
    :param config: the shipped model file (``model_config=``)
    :param description: one line for tables and help
    """

    name: str
    config: str
    description: str


#: the drive variants by name
DRIVE_VARIANTS: Mapping[str, DriveVariant] = MappingProxyType({
    "soft": DriveVariant("soft", "model_soft",
                         "softest drive the wind-load evidence admits (weakest wind loads)"),
    "stiff": DriveVariant("stiff", "model_stiff",
                          "stiffest in-range drive that still meets Table 4 (strongest wind loads)"),
})

__all__ = ["DRIVE_VARIANTS", "DriveVariant"]
