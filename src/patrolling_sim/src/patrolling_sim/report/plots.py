"""Report figures (matplotlib, object API with the Agg canvas: no display, no pyplot state).

- :func:`boxplot_figure`   idleness samples per algorithm and team size, one figure per map;
- :func:`timeplot_figure`  idleness samples over simulated time, one figure per run;
- :func:`heatmap_figure`   per-vertex average idleness drawn on the map with the patrol graph,
  one panel per algorithm, one figure per (map, N, settings) group, shared colour scale;
- :func:`histogram_figure` idleness histograms (fraction of samples per bin), one figure per
  (map, N, settings) group, one step curve per algorithm.

Every function returns a :class:`matplotlib.figure.Figure`; :func:`save` writes it as PNG.
"""
import math
import re

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import matplotlib
from matplotlib import cm, colors as mcolors

IDL_LABEL = "Idleness (s)"
TIME_LABEL = "Simulated time (s)"
DPI = 100


def _cmap(name):
    return matplotlib.colormaps[name]


def slug(*parts):
    """File-name-safe name from parts."""
    s = "_".join(str(p) for p in parts if p not in (None, ""))
    return re.sub(r"[^A-Za-z0-9.=-]+", "_", s).strip("_") or "x"


def save(fig, path):
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=DPI)
    return path


def algorithm_colors(algorithms):
    """Stable colour per algorithm name (tab10/tab20 by sorted name)."""
    algs = sorted(set(algorithms))
    cmap = _cmap("tab10" if len(algs) <= 10 else "tab20")
    return {a: cmap(i % cmap.N) for i, a in enumerate(algs)}


def boxplot_figure(title, boxes, colors, refs=None):
    """boxes: list of (label, algorithm, samples array). Whiskers 1.5 IQR, outliers as dots,
    means as white diamonds. refs: per box, the theoretical references of its map and team
    size (:class:`patrolling_sim.planning.references.References` at 1 m/s, or None), drawn as short
    lines across the box: dashed the cyclic reference L/(N v), dotted the partition one."""
    n = len(boxes)
    fig = Figure(figsize=(max(6.0, 0.75 * n + 2.0), 5.0))
    ax = fig.add_subplot(1, 1, 1)
    data = [b[2] if len(b[2]) else np.array([np.nan]) for b in boxes]
    bp = ax.boxplot(data, labels=[b[0] for b in boxes], showmeans=True, patch_artist=True,
                    flierprops=dict(marker=".", markersize=3, alpha=0.4),
                    meanprops=dict(marker="D", markerfacecolor="white",
                                   markeredgecolor="black", markersize=5),
                    medianprops=dict(color="black"))
    for patch, b in zip(bp["boxes"], boxes):
        patch.set_facecolor(colors[b[1]])
        patch.set_alpha(0.75)
    labelled = set()
    for i, r in enumerate(refs or []):
        if r is None:
            continue
        for value, style, name in ((r.cyclic_idleness, "--", "cyclic reference L/(N v)"),
                                   (r.partition_idleness, ":", "partition reference")):
            ax.hlines(value, i + 0.6, i + 1.4, colors="black", linestyles=style, linewidth=1.2,
                      label=None if name in labelled else name + " (1 m/s)")
            labelled.add(name)
    if labelled:
        ax.legend(loc="upper right", fontsize="small")
    ax.set_ylabel(IDL_LABEL)
    ax.set_xlabel("Algorithm and team size N (box: quartiles, line: median, diamond: mean)")
    ax.set_title(title)
    ax.set_ylim(bottom=0)
    ax.grid(axis="y", alpha=0.3)
    if n > 8:
        for t in ax.get_xticklabels():
            t.set_rotation(45)
            t.set_ha("right")
    fig.tight_layout()
    return fig


def timeplot_figure(title, samples, n_robots):
    """Scatter of each idleness sample at its (simulated) visit time, coloured by robot,
    with the running mean of all samples so far."""
    fig = Figure(figsize=(10.0, 4.0))
    ax = fig.add_subplot(1, 1, 1)
    t = samples["Time"].to_numpy(dtype=float)
    y = samples["Idleness"].to_numpy(dtype=float)
    robots = samples["Robot"].to_numpy()
    if t.size:
        order = np.argsort(t, kind="stable")
        ids = sorted(set(robots.tolist()))
        cmap = _cmap("tab10" if len(ids) <= 10 else "viridis")
        for k, rid in enumerate(ids):
            m = robots == rid
            c = cmap(k % 10) if len(ids) <= 10 else cmap(k / max(1, len(ids) - 1))
            ax.scatter(t[m], y[m], s=8, color=c, alpha=0.6,
                       label=f"robot {rid}" if len(ids) <= 12 else None)
        run_mean = np.cumsum(y[order]) / np.arange(1, t.size + 1)
        ax.plot(t[order], run_mean, color="black", lw=1.5, label="running mean")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, framealpha=0.8,
                  ncol=1 if len(ids) <= 14 else 2, borderaxespad=0.0)
        ax.set_ylim(bottom=0, top=max(1.0, float(y.max())) * 1.15)
    else:
        ax.text(0.5, 0.5, "no idleness samples", transform=ax.transAxes, ha="center")
    ax.set_xlabel(TIME_LABEL)
    ax.set_ylabel(IDL_LABEL)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _nice_ceil(x):
    """Smallest 1, 2 or 5 times a power of ten that is >= x (x > 0)."""
    k = math.floor(math.log10(x))
    for m in (1, 2, 5, 10):
        if m * 10 ** k >= x * (1 - 1e-12):
            return float(m * 10 ** k)
    return float(10 ** (k + 1))


def histogram_bins(values, top=None):
    """Bin edges from 0 and their width: the Freedman-Diaconis width of the samples
    rounded up to a 'nice' value (1, 2, 5, 10, 20, ... s), at least 1 s, at most 300 bins
    up to ``top`` (default: the largest sample)."""
    v = np.asarray(values, dtype=float)
    if top is None:
        top = float(v.max()) if v.size else 1.0
    top = max(1.0, float(top))
    width = 1.0
    if v.size > 1:
        q75, q25 = np.percentile(v, [75, 25])
        fd = 2.0 * (q75 - q25) / v.size ** (1.0 / 3.0)
        if fd > 1.0:
            width = _nice_ceil(fd)
    while top / width > 300:
        width = _nice_ceil(width * 1.01)
    return np.arange(0.0, math.floor(top / width) * width + 2 * width, width), width


TAIL_QUANTILE = 99.5


def histogram_figure(title, series, colors):
    """series: list of (label, algorithm, samples array). One panel per series (shared
    axes); the x axis stops at the 99.5th percentile of all samples, the number of samples
    beyond is written in each panel."""
    series = [s for s in series if len(s[2])] or series[:1]
    k = len(series)
    fig = Figure(figsize=(9.0, 1.2 + 1.6 * k))
    pooled = (np.concatenate([s for _, _, s in series]) if series and len(series[0][2])
              else np.array([]))
    cut = float(np.percentile(pooled, TAIL_QUANTILE)) if pooled.size else 1.0
    full = float(pooled.max()) if pooled.size else 1.0
    bins, width = histogram_bins(pooled[pooled <= cut] if pooled.size else pooled,
                                 top=cut if cut < full else full)
    axes = []
    for i, (label, alg, s) in enumerate(series):
        ax = fig.add_subplot(k, 1, i + 1, sharex=axes[0] if axes else None,
                             sharey=axes[0] if axes else None)
        axes.append(ax)
        if len(s):
            # one filled step artist per panel: ax.hist drew one patch per bin, and the
            # histograms of a large campaign took most of its report's drawing time
            counts, _ = np.histogram(s, bins=bins)
            ax.stairs(counts / len(s), bins, fill=True, color=colors[alg], alpha=0.85)
            beyond = int((s > bins[-1]).sum())
            note = f"{len(s)} samples, mean {np.mean(s):.1f} s"
            if beyond:
                note += f"; {beyond} beyond {bins[-1]:g} s (max {np.max(s):.1f} s)"
            ax.text(0.99, 0.9, note, transform=ax.transAxes, ha="right", va="top", fontsize=8)
        ax.set_title(label, fontsize=9, loc="left")
        ax.set_ylabel("Fraction of\nsamples", fontsize=8)
        ax.grid(alpha=0.3)
        if i < k - 1:
            ax.tick_params(labelbottom=False)
    axes[-1].set_xlabel(f"{IDL_LABEL}  (bins of {width:g} s)")
    axes[0].set_xlim(0, bins[-1])
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def heatmap_figure(title, occupancy, graph, panels):
    """panels: list of (panel title, {vertex: average idleness}). Vertices without samples
    are drawn as hollow grey circles. One colour scale shared by all panels."""
    k = len(panels)
    w_m, h_m = occupancy.size_m
    aspect = h_m / w_m if w_m else 1.0
    # wide maps get fewer, wider panels
    ncols = min(k, 3 if aspect >= 0.75 else (2 if aspect >= 0.45 else 1))
    nrows = int(math.ceil(k / ncols))
    pw = {1: 7.5 if aspect >= 0.75 else 12.0, 2: 7.0}.get(ncols, 5.5)
    fig = Figure(figsize=(pw * ncols + 1.2, max(3.0, pw * aspect * nrows + 0.9 * nrows + 0.6)))
    vals = [v for _, d in panels for v in d.values()]
    vmin = min(vals) if vals else 0.0
    vmax = max(vals) if vals else 1.0
    if vmax <= vmin:
        vmax = vmin + 1.0
    norm = mcolors.Normalize(vmin=vmin, vmax=vmax)
    cmap = _cmap("inferno_r")
    ox, oy = occupancy.origin[0], occupancy.origin[1]
    extent = (ox, ox + w_m, oy, oy + h_m)
    img = occupancy.to_image()
    pos = {v: graph.nodes[v]["pos"] for v in graph.nodes}
    edges = {(min(u, w), max(u, w)) for u, w in graph.edges() if u != w}
    n_v = graph.number_of_nodes()
    # marker diameter: 60 % of the median nearest-vertex distance, 5..14 points
    xy = np.array([pos[v] for v in sorted(pos)], dtype=float)
    if len(xy) > 1:
        d = np.sqrt(((xy[:, None, :] - xy[None, :, :]) ** 2).sum(-1))
        np.fill_diagonal(d, np.inf)
        spacing = float(np.median(d.min(axis=1)))
    else:
        spacing = max(w_m, h_m) / 10.0
    pts_per_m = pw * 72.0 / max(w_m, 1e-6)
    size = float(np.clip(0.6 * spacing * pts_per_m, 5.0, 14.0)) ** 2
    axes = []
    for i, (ptitle, avg) in enumerate(panels):
        ax = fig.add_subplot(nrows, ncols, i + 1)
        axes.append(ax)
        ax.imshow(img, cmap="gray", vmin=0, vmax=255, extent=extent, origin="upper",
                  interpolation="nearest", alpha=0.55)
        for u, w in sorted(edges):
            (x1, y1), (x2, y2) = pos[u], pos[w]
            ax.plot([x1, x2], [y1, y2], color="#2e8b57", lw=1.2, alpha=0.8, zorder=2)
        seen = [v for v in sorted(pos) if v in avg]
        unseen = [v for v in sorted(pos) if v not in avg]
        if unseen:
            ax.scatter([pos[v][0] for v in unseen], [pos[v][1] for v in unseen], s=size,
                       facecolors="none", edgecolors="grey", lw=1.2, zorder=3)
        if seen:
            ax.scatter([pos[v][0] for v in seen], [pos[v][1] for v in seen], s=size,
                       c=[avg[v] for v in seen], cmap=cmap, norm=norm, edgecolors="black",
                       lw=0.6, zorder=3)
        if n_v <= 80:
            for v in sorted(pos):
                ax.annotate(str(v), pos[v], xytext=(4, 4), textcoords="offset points",
                            fontsize=7 if n_v <= 40 else 5, color="#1f3f9f", zorder=4)
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(ptitle, fontsize=10)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0, 0.9, 0.97))
    cax = fig.add_axes((0.915, 0.12, 0.018, 0.74))
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, cax=cax, label="Average idleness per vertex (s)")
    return fig
