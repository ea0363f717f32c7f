"""The mismatch map: where, after calibration, the model still disagrees with the recording.

The recording is cut into windows from its speed schedule
(:func:`thermodrift.core.recording.schedule_windows`, on the one speed segmenter): each speed change opens
a short ``step`` window (the first ``step_s`` seconds, where instantaneous growth, sensor lag and fast modes
show), followed by the rest of the block as ``running`` or ``stopped``. For every channel and window the map
holds the share of the calibration objective (the sum of squared residuals divided by each channel's weight σ,
see :mod:`thermodrift.core.physics.calibration.objective`) that falls there, the RMS and mean residual in the channel's
unit (K or µm), and the share relative to the window's length (``excess``: 1 is what a uniformly spread misfit
gives; ≫ 1 marks a localised mismatch). Cells, windows and channels are ranked by their share; the missing-
physics finder starts from the top of that list.

Outputs: :meth:`MismatchMap.to_dict` (``mismatch.json``), :func:`plot_heatmap` (time × channel PNG),
:func:`plot_before_after` (measured, initial guess, calibrated). Logging them is the verb's
(``thermodrift calibrate``, through :func:`thermodrift.core.tracking.log_calibration`); this module only
computes and draws.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from thermodrift.core.metrics import rms
import pandas as pd

from thermodrift.core.physics.calibration import CalibrationResult
from thermodrift.core.recording import STEP_WINDOW_S, Window, schedule_windows


@dataclass
class MismatchMap:
    """Residual shares per (channel, window); see the module docstring."""

    windows: list[Window]
    cells: pd.DataFrame       # one row per (channel, window): share, excess, rms, mean, samples
    total_weighted_rss: float

    def ranked_cells(self, top: int | None = None) -> pd.DataFrame:
        cells = self.cells.sort_values("share", ascending=False)
        return cells if top is None else cells.head(top)

    def by_window(self) -> pd.DataFrame:
        """Windows ranked by their share of the objective (summed over channels)."""
        g = self.cells.groupby("window", sort=False).agg(share=("share", "sum"), kind=("kind", "first"),
                                                         start_h=("start_h", "first"), end_h=("end_h", "first"),
                                                         time_fraction=("time_fraction", "first"))
        g["excess"] = g["share"] / g["time_fraction"].where(g["time_fraction"] > 0)
        top = self.cells.loc[self.cells.groupby("window", sort=False)["share"].idxmax(), ["window", "channel"]]
        g["top_channel"] = top.set_index("window")["channel"]
        return g.sort_values("share", ascending=False)

    def by_channel(self) -> pd.DataFrame:
        """Channels ranked by their share of the objective (summed over windows)."""
        g = self.cells.groupby("channel", sort=False).agg(share=("share", "sum"), kind=("kind_channel", "first"))
        top = self.cells.loc[self.cells.groupby("channel", sort=False)["share"].idxmax(), ["channel", "window"]]
        g["top_window"] = top.set_index("channel")["window"]
        return g.sort_values("share", ascending=False)

    def to_dict(self, top: int = 30) -> dict[str, Any]:
        def records(df: pd.DataFrame, index_name: str) -> list[dict]:
            return [{index_name: str(i), **{k: _plain(v) for k, v in row.items()}} for i, row in df.iterrows()]

        cells = self.ranked_cells(top)
        return {
            "objective": "sum over channels of (residual / weight sigma)^2; share = fraction of it in a cell",
            "total_weighted_rss": self.total_weighted_rss,
            "windows": [{"name": w.name, "kind": w.kind, "start_h": w.start_s / 3600.0, "end_h": w.end_s / 3600.0,
                         "speed_rpm": w.speed_rpm} for w in self.windows],
            "ranked_windows": records(self.by_window(), "window"),
            "ranked_channels": records(self.by_channel(), "channel"),
            "ranked_cells": [{k: _plain(v) for k, v in row.items()} for _, row in cells.iterrows()],
        }


def _plain(v: Any) -> Any:
    if isinstance(v, (np.floating, float)):
        return float(v) if np.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def mismatch_map(result: CalibrationResult, windows: Sequence[Window] | None = None,
                 step_s: float = STEP_WINDOW_S) -> MismatchMap:
    """The mismatch map of a calibration (residuals of the calibrated model on the full recording)."""
    t = result.time_s
    windows = list(windows) if windows is not None else schedule_windows(t, result.speed_rpm, step_s)
    resid = result.residuals
    z2 = (resid / pd.Series(result.weight)) ** 2
    total = float(z2.to_numpy().sum())
    span = float(windows[-1].end_s - windows[0].start_s) if windows else 1.0
    rows = []
    R, Z2 = resid.to_numpy(), z2[resid.columns].to_numpy()
    # windows are time ranges of a sorted index: slices, so the map costs O(samples + windows × channels)
    bounds = np.searchsorted(t, [[w.start_s, w.end_s] for w in windows]) if windows else np.empty((0, 2), int)
    for w, (a, b) in zip(windows, bounds):
        frac = (w.end_s - w.start_s) / span
        for j, ch in enumerate(resid.columns):
            r = R[a:b, j]
            share = float(Z2[a:b, j].sum()) / total if total > 0 else 0.0
            rows.append({"channel": ch, "window": w.name, "kind": w.kind, "kind_channel": result.channel_kind[ch],
                         "start_h": w.start_s / 3600.0, "end_h": w.end_s / 3600.0, "time_fraction": frac,
                         "share": share, "excess": share * len(resid.columns) / frac if frac > 0 else np.nan,
                         "rms": float(rms(r)) if len(r) else np.nan,
                         "mean": float(np.mean(r)) if len(r) else np.nan, "samples": int(b - a),
                         "unit": "K" if result.channel_kind[ch] == "temperature" else "um"})
    return MismatchMap(windows, pd.DataFrame(rows), total)


def plot_heatmap(mm: MismatchMap, path: str | Path, speed: tuple[np.ndarray, np.ndarray] | None = None) -> Path:
    """Time × channel heatmap of each cell's share of the objective (%), with the speed schedule on top."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    channels = list(dict.fromkeys(mm.cells["channel"]))
    edges = np.r_[[w.start_s for w in mm.windows], mm.windows[-1].end_s] / 3600.0
    grid = mm.cells.pivot_table(index="channel", columns="window", values="share", sort=False)
    grid = grid.reindex(index=channels, columns=[w.name for w in mm.windows]).to_numpy() * 100.0
    positive = grid[grid > 0]
    norm = LogNorm(vmin=max(positive.min(), positive.max() * 1e-4), vmax=positive.max()) if len(positive) else None
    fig, (ax_s, ax) = plt.subplots(2, 1, figsize=(12, 2.0 + 0.28 * len(channels)), sharex=True,
                                   gridspec_kw={"height_ratios": [1, max(3, len(channels) / 3)]})
    if speed is not None:
        ax_s.plot(speed[0] / 3600.0, speed[1], color="k", lw=0.8)
    ax_s.set_ylabel("rpm")
    mesh = ax.pcolormesh(edges, np.arange(len(channels) + 1), np.clip(grid, norm.vmin if norm else 0, None),
                         cmap="magma_r", norm=norm, shading="flat")
    ax.set_yticks(np.arange(len(channels)) + 0.5, channels, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("time (h)")
    fig.colorbar(mesh, ax=[ax_s, ax], label="share of weighted residual sum of squares (%)")
    ax_s.set_title("Mismatch map: where the calibrated model misses (windows from the speed schedule)")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return Path(path)


def plot_before_after(result: CalibrationResult, path: str | Path, mm: MismatchMap | None = None,
                      extra_temperatures: int = 3) -> Path:
    """Measured vs initial guess vs calibrated: every displacement channel plus the temperature channels that
    carry most of the mismatch (``extra_temperatures``)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    disp = [c for c, k in result.channel_kind.items() if k == "displacement"]
    temps = [c for c, k in result.channel_kind.items() if k == "temperature"]
    if mm is not None:
        ranked = [c for c in mm.by_channel().index if c in temps]
        temps = ranked[:extra_temperatures]
    else:
        temps = temps[:extra_temperatures]
    chans = disp + temps
    fig, axes = plt.subplots(len(chans), 1, figsize=(11, 1.9 * len(chans) + 0.5), sharex=True, squeeze=False)
    h = result.time_s / 3600.0
    for ax, c in zip(axes[:, 0], chans):
        unit = "µm" if result.channel_kind[c] == "displacement" else "°C"
        ax.plot(h, result.measured[c], color="k", lw=0.7, label="measured")
        ax.plot(h, result.predicted_initial[c], color="tab:blue", lw=0.8, ls="--",
                label=f"before (initial guess), RMSE {result.rmse_initial[c]:.3g} {unit}")
        ax.plot(h, result.predicted[c], color="tab:red", lw=0.9,
                label=f"after (calibrated), RMSE {result.rmse[c]:.3g} {unit}")
        ax.set_ylabel(f"{c}", fontsize=8)
        ax.legend(fontsize=7, loc="upper left", ncol=3, frameon=False)
    axes[-1, 0].set_xlabel("time (h)")
    fig.suptitle(f"Calibration of network {result.network.name!r}: before and after", y=1.0)
    fig.tight_layout()
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)
    return Path(path)

