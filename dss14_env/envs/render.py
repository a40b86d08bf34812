"""Matplotlib rendering of the DSS14 environment: recent servo errors, rate commands and wind.

``rgb_array`` draws on an off-screen Agg canvas (no pyplot, no window); ``human`` draws the
same figure through pyplot and shows it when the backend is interactive.  History is kept
only when a render mode is set, so rendering costs nothing otherwise; the environment adds the
steps of a noise block to it from its step block when it draws or replaces the block, not per
step (``rgb_array``).
"""

from __future__ import annotations

from collections import deque

import numpy as np

_FIELDS = ("t", "e_az", "e_el", "r_az", "r_el", "cd_az", "cd_el", "wind")


class Renderer:
    """Ring buffer of recent samples and the figure drawn from it.

    :param mode: ``"rgb_array"`` or ``"human"``
    :param dt: sample period, s
    :param window_s: shown time window, s
    """

    def __init__(self, mode: str, dt: float, window_s: float) -> None:
        if mode not in ("rgb_array", "human"):
            raise ValueError(f"render_mode must be None, 'rgb_array' or 'human', got {mode!r}")
        self.mode = mode
        self.maxlen = max(2, int(round(window_s / dt)) + 1)
        self.samples: deque[tuple[float, ...]] = deque(maxlen=self.maxlen)  # one tuple of _FIELDS a step
        self.title = ""
        self._fig = None
        self._lines = None

    def __getstate__(self) -> dict:
        """The history and settings; the figure is drawn again by the copy when it renders."""
        state = self.__dict__.copy()
        for key in ("_fig", "_axs", "_lines", "_suptitle"):
            state.pop(key, None)
        state["_fig"] = state["_lines"] = None
        return state

    def reset(self, title: str) -> None:
        """Forget the history; ``title`` labels the figure (scenario, wind)."""
        self.samples.clear()
        self.title = title

    def record(self, t: float, e_az: float, e_el: float, r_az: float, r_el: float,
               cd_az: float, cd_el: float, wind: float) -> None:
        """Add one sample: time (s), true servo errors (mdeg), applied and commanded rates
        (deg/s), wind speed (m/s).
        """
        self.samples.append((t, e_az, e_el, r_az, r_el, cd_az, cd_el, wind))

    def extend(self, *columns: np.ndarray) -> None:
        """Add several samples: one array per field of :meth:`record`, in its order."""
        self.samples.extend(zip(*(np.asarray(c, float).tolist() for c in columns), strict=True))

    # ------------------------------------------------------------------ drawing
    def _build(self) -> None:
        if self.mode == "human":
            import matplotlib.pyplot as plt

            fig = plt.figure(figsize=(6.4, 4.8), dpi=100)
        else:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            fig = Figure(figsize=(6.4, 4.8), dpi=100)
            FigureCanvasAgg(fig)
        axs = fig.subplots(3, 1, sharex=True)
        lines = {}
        lines["e_az"], = axs[0].plot([], [], lw=1.0, label="az")
        lines["e_el"], = axs[0].plot([], [], lw=1.0, label="el")
        axs[0].set_ylabel("servo error\n(mdeg)")
        lines["r_az"], = axs[1].plot([], [], lw=1.0, label="az rate command")
        lines["r_el"], = axs[1].plot([], [], lw=1.0, label="el rate command")
        lines["cd_az"], = axs[1].plot([], [], "--", lw=0.8, color="C0", label="az trajectory rate")
        lines["cd_el"], = axs[1].plot([], [], "--", lw=0.8, color="C1", label="el trajectory rate")
        axs[1].set_ylabel("rate\n(deg/s)")
        lines["wind"], = axs[2].plot([], [], lw=1.0, color="C2")
        axs[2].set_ylabel("wind\n(m/s)")
        axs[2].set_xlabel("time (s)")
        axs[0].legend(loc="upper left", fontsize=7)
        axs[1].legend(loc="upper left", fontsize=7, ncol=2)
        fig.tight_layout(rect=(0, 0, 1, 0.95))
        self._fig, self._axs, self._lines = fig, axs, lines
        self._suptitle = fig.suptitle("", fontsize=9)

    def _update(self) -> None:
        if self._fig is None:
            self._build()
        h = np.asarray(self.samples, float).reshape(-1, len(_FIELDS))
        cols = dict(zip(_FIELDS, h.T, strict=True))
        t = cols["t"]
        for k, line in self._lines.items():
            line.set_data(t, cols[k])
        for ax in self._axs:
            ax.relim()
            ax.autoscale_view()
        if t.size > 1:
            self._axs[0].set_xlim(t[0], max(t[-1], t[0] + 1e-9))
        self._suptitle.set_text(self.title)

    def rgb(self) -> np.ndarray:
        """The current figure as an ``(H, W, 3)`` uint8 array."""
        self._update()
        self._fig.canvas.draw()
        return np.asarray(self._fig.canvas.buffer_rgba())[..., :3].copy()

    def show(self) -> None:
        """Redraw the pyplot window (``human`` mode)."""
        import matplotlib
        import matplotlib.pyplot as plt

        first = self._fig is None
        self._update()
        if first and "agg" not in matplotlib.get_backend().lower():
            plt.show(block=False)
        self._fig.canvas.draw_idle()
        self._fig.canvas.flush_events()

    def close(self) -> None:
        """Release the figure."""
        if self._fig is not None and self.mode == "human":
            import matplotlib.pyplot as plt

            plt.close(self._fig)
        self._fig = None
        self._lines = None
