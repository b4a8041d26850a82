"""Benchmark metrics against numbers derived by hand."""

import numpy as np
import torch

from simlidar.bench import metrics
from simlidar.models.registry import build_model, load_recipe


def test_macs_of_the_papers_cnn_by_hand():
    model = build_model(load_recipe("cnn"), (1, 16, 16), 32, torch.Generator().manual_seed(0))
    counted = metrics.macs(model, torch.rand(1, 16, 16))
    conv1 = 48 * 8 * 8 * (1 * 5 * 5)  # 16 x 16 -> 8 x 8 (5x5, stride 2, pad 2)
    conv2 = 24 * 4 * 4 * (48 * 5 * 5)  # 8 x 8 -> 4 x 4
    dense = 24 * 4 * 4 * 256 + 256 * 32
    assert counted["macs"] == conv1 + conv2 + dense == 644_096
    assert 0.0 <= counted["activation_sparsity"] <= 1.0


def test_footprint_and_connection_sparsity():
    model = torch.nn.Sequential(torch.nn.Linear(4, 3), torch.nn.BatchNorm1d(3))
    with torch.no_grad():
        model[0].weight[:2] = 0.0  # 8 of 12 weights
    figures = metrics.footprint(model)
    assert figures["params"] == 4 * 3 + 3 + 3 + 3
    # float32 parameters and buffers (running mean and var), plus int64 num_batches_tracked
    assert figures["footprint"] == 4 * (12 + 3 + 3 + 3 + 3 + 3) + 8
    assert figures["connection_sparsity"] == 8 / 12


def test_confusion_matrix_counts_undecided_samples_apart():
    labels = np.array([0, 0, 1, 2, 2])
    predicted = np.array([0, 1, 1, -1, 2])
    matrix = metrics.confusion_matrix(labels, predicted, 3)
    assert matrix.tolist() == [[1, 1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1]]


def test_latency_and_board_energy():
    model = build_model(load_recipe("cnn"), (1, 16, 16), 4)
    x = torch.rand(40, 1, 16, 16)
    figures = metrics.conventional_figures(model, x, board_power_w=10.0)
    assert figures["latency_ms"] > 0 and figures["throughput_per_s"] > 0
    assert figures["throughput_batch"] == 40
    # power x latency: 10 W = 1e13 pJ/s, times t ms = t 1e-3 s
    assert np.isclose(figures["energy_pj_board"], 10.0 * figures["latency_ms"] * 1e9)
    assert figures["energy_pj_mac"] == figures["macs"] * metrics.MAC_PJ
