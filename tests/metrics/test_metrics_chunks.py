"""The robot-side metrics run their forward kinematics in chunks of frames (bounded memory on long
recordings, docs/RESULTS.md "reliability"): the figures are those of one batch of the whole recording."""

from __future__ import annotations

import numpy as np
import pytest

import nlo_lab.metrics as metrics


@pytest.mark.parametrize("robot_name", ["yumi", "nao"])
def test_chunked_metrics_equal_one_batch(robot_name, robot64, random_angles, make_demo, monkeypatch):
    robot = robot64(robot_name)
    q = random_angles(robot, 23, 5).numpy()  # random angles: some frames collide, the arms wander
    demo = make_demo(T=23, fps=10.0)
    monkeypatch.setattr(metrics, "METRIC_CHUNK_FRAMES", 10**6)
    whole_errors, whole_colliding = metrics.tracking_errors(demo, robot, q), metrics.self_collision_frames(robot, q)
    monkeypatch.setattr(metrics, "METRIC_CHUNK_FRAMES", 5)  # 5 + 5 + 5 + 5 + 3 frames
    assert list(metrics._chunks(23)) == [slice(0, 5), slice(5, 10), slice(10, 15), slice(15, 20), slice(20, 23)]
    chunked_errors, chunked_colliding = metrics.tracking_errors(demo, robot, q), metrics.self_collision_frames(robot, q)
    assert 0 < whole_colliding < 23 and chunked_colliding == whole_colliding
    assert chunked_errors.keys() == whole_errors.keys()
    for key, value in whole_errors.items():
        np.testing.assert_allclose(chunked_errors[key], value, rtol=1e-12, err_msg=key)
