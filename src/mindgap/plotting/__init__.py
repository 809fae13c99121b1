"""Figures: reward and policy heatmaps, learning curves (matplotlib, Agg backend)."""

import matplotlib

matplotlib.use("Agg")
