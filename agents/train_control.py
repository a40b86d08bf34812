"""What a user sees of a training run and how they stop it: two stable-baselines3 callbacks.

* :func:`progress_callback`: the run's environment steps as a :class:`~dss14_env.core.progress.Progress`
  (a bar with its ETA on a terminal, a line every tenth of the run otherwise);
* :func:`stop_callback`: ends the training at the next environment step once a SIGINT or SIGTERM
  was recorded by a :class:`~dss14_env.core.stop.StopRequests`, so that the run saves a
  checkpoint of where it stopped (:func:`dss14_env.agents.train.train`).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

from dss14_env.core.progress import Progress
from dss14_env.core.stop import StopRequests, signal_name


def progress_callback(total: int, start: int, desc: str, enabled: bool = True) -> Any:
    """A callback that shows the run's environment steps, from ``start`` to ``total``."""
    from stable_baselines3.common.callbacks import BaseCallback

    class StepProgress(BaseCallback):
        """The environment steps as a :class:`Progress`."""

        def __init__(self) -> None:
            super().__init__()
            self.progress: Progress | None = None

        def _on_training_start(self) -> None:
            self.progress = Progress(total, desc, unit="steps", enabled=enabled, initial=start)

        def _on_step(self) -> bool:
            if self.progress is not None:
                self.progress.update_to(self.num_timesteps)
            return True

        def _on_training_end(self) -> None:
            if self.progress is not None:
                self.progress.close()

        def write(self, line: str) -> None:
            """A message line that does not break the bar."""
            if self.progress is not None:
                self.progress.write(line)
            else:
                print(line, file=sys.stderr, flush=True)

    return StepProgress()


def stop_callback(requests: StopRequests, say: Callable[[str], None] | None = None) -> Any:
    """A callback that ends the training at the first step after a recorded stop signal.

    :param say: where its one message goes (default: a line on stderr); a progress callback's
        ``write`` keeps the bar whole
    """
    from stable_baselines3.common.callbacks import BaseCallback

    class StopOnSignal(BaseCallback):
        """Returns False (SB3: stop training) once ``requests`` holds a signal."""

        def __init__(self) -> None:
            super().__init__()
            self.told = False

        def _on_step(self) -> bool:
            if requests.signum is None:
                return True
            if not self.told:
                line = (f"{signal_name(requests.signum)}: stopping at {self.num_timesteps} steps and "
                        f"saving a checkpoint (a second one stops at once, without it)")
                if say is not None:
                    say(line)
                else:
                    print(line, file=sys.stderr, flush=True)
                self.told = True
            return False

    return StopOnSignal()


__all__ = ["progress_callback", "stop_callback"]
