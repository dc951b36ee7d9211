"""Shared noisy test path for the smoother tests."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def clean_path() -> np.ndarray:
    """(200, 2) S-curve x = t, y = 2 sin(t/3), metres."""
    t = np.linspace(0.0, 20.0, 200)
    return np.c_[t, 2.0 * np.sin(t / 3.0)]


@pytest.fixture
def noisy_path(clean_path: np.ndarray) -> np.ndarray:
    """The S-curve with seeded N(0, 5 cm) noise on every coordinate."""
    return clean_path + np.random.default_rng(1234).normal(0.0, 0.05, clean_path.shape)
