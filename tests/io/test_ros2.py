"""``beacon-sim export --ros2``: a ROS 2 bag that rosbags reads back with its ROS 2 typestore,
equal message by message to the run's tables (office with mcl, slam_loop with its SLAM filters)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rosbags.rosbag2 import Reader

from beacon_sim.cli.main import main
from beacon_sim.core.raycast import beam_angles
from beacon_sim.core.scenario import load_scenario
from beacon_sim.io.export import load_export
from beacon_sim.io.ros2 import bag_folder, typestore

STORE = typestore()


def export_both(tmp_path, scenario: str, seconds: float, storage: str):
    """The same headless run exported as .npz (the tables) and as a ROS 2 bag."""
    npz, bag = tmp_path / "run.npz", tmp_path / f"bag{storage}"
    common = [scenario, "--seed", "3", "--duration", str(seconds)]
    assert main(["export", *common, "--out", str(npz)]) == 0
    assert main(["export", *common, "--out", str(bag), "--ros2"]) == 0
    return load_export(npz), bag_folder(bag)


def read_bag(folder):
    """topic -> [(log time ns, msgtype, message)] in the bag's order."""
    out: dict[str, list] = {}
    with Reader(folder) as reader:
        for conn, ns, raw in reader.messages():
            msg = STORE.deserialize_cdr(raw, conn.msgtype)
            out.setdefault(conn.topic, []).append((ns, conn.msgtype, msg))
    return out


def stamp_ns(header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def check_pose(pose, x, y, theta):
    """Position exactly the table's; orientation the rotation by theta about +z, exactly."""
    assert (pose.position.x, pose.position.y, pose.position.z) == (x, y, 0.0)
    q = pose.orientation
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2))


def compose(a, b):
    """Pose ``a`` then pose ``b`` (in ``a``'s frame): (x, y, theta)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    th = math.remainder(a[2] + b[2], 2 * math.pi)
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], th)


def yaw(q) -> float:
    return 2 * math.atan2(q.z, q.w)


def check_common(tabs, msgs, dt: float):
    truth, est = tabs["truth"], tabs["estimates"]
    n = len(truth["tick"])
    dt_ns = round(dt * 1e9)
    # /truth: one nav_msgs/Odometry per tick, the table's pose and command
    rows = msgs["/truth"]
    assert len(rows) == n
    for k, (ns, kind, m) in enumerate(rows):
        assert kind == "nav_msgs/msg/Odometry" and ns == stamp_ns(m.header) == k * dt_ns
        assert (m.header.frame_id, m.child_frame_id) == ("map", "base_link")
        check_pose(m.pose.pose, truth["x_m"][k], truth["y_m"][k], truth["theta_rad"][k])
        v = 0.0 if k == 0 else truth["v_mps"][k]
        w = 0.0 if k == 0 else truth["omega_radps"][k]
        assert (m.twist.twist.linear.x, m.twist.twist.angular.z) == (v, w)
    # /tf: map -> odom -> base_link is the truth; odom -> base_link the command's dead reckoning
    odom = (0.0, 0.0, 0.0)
    assert len(msgs["/tf"]) == n
    for k, (ns, kind, m) in enumerate(msgs["/tf"]):
        assert kind == "tf2_msgs/msg/TFMessage" and ns == k * dt_ns
        a, b = m.transforms
        assert (a.header.frame_id, a.child_frame_id, b.header.frame_id, b.child_frame_id) == \
            ("map", "odom", "odom", "base_link")
        if k > 0:
            v, w = truth["v_mps"][k], truth["omega_radps"][k]
            odom = (odom[0] + v * dt * math.cos(odom[2]), odom[1] + v * dt * math.sin(odom[2]),
                    math.remainder(odom[2] + w * dt, 2 * math.pi))
        tb = b.transform
        np.testing.assert_allclose([tb.translation.x, tb.translation.y], odom[:2], atol=1e-9)
        assert abs(math.remainder(yaw(tb.rotation) - odom[2], 2 * math.pi)) < 1e-9
        ta = a.transform
        whole = compose((ta.translation.x, ta.translation.y, yaw(ta.rotation)),
                        (tb.translation.x, tb.translation.y, yaw(tb.rotation)))
        np.testing.assert_allclose(whole[:2], [truth["x_m"][k], truth["y_m"][k]], atol=1e-9)
        assert abs(math.remainder(whole[2] - truth["theta_rad"][k], 2 * math.pi)) < 1e-9
    assert [m.header.frame_id for _, _, m in msgs["/odom"]] == ["odom"] * n
    # /filters/NAME/pose: one PoseWithCovarianceStamped per row of the estimates table
    names = list(dict.fromkeys(est["filter"].tolist()))
    assert names
    for name in names:
        rows = np.flatnonzero(est["filter"] == name)
        got = msgs[f"/filters/{name}/pose"]
        assert len(got) == len(rows)
        for r, (ns, kind, m) in zip(rows, got, strict=True):
            assert kind == "geometry_msgs/msg/PoseWithCovarianceStamped"
            assert ns == stamp_ns(m.header) == int(est["tick"][r]) * dt_ns and m.header.frame_id == "map"
            check_pose(m.pose.pose, est["x_m"][r], est["y_m"][r], est["theta_rad"][r])
            c = m.pose.covariance.reshape(6, 6)
            want = np.zeros((6, 6))
            for (i, j), col in zip(((0, 0), (0, 1), (0, 5), (1, 1), (1, 5), (5, 5)),
                                   ("cov_xx", "cov_xy", "cov_xt", "cov_yy", "cov_yt", "cov_tt"), strict=True):
                want[i, j] = want[j, i] = est[col][r]
            np.testing.assert_array_equal(c, want)
    return names


def test_office_mcl_bag_equals_the_tables(tmp_path):
    tabs, folder = export_both(tmp_path, "office", 6.0, ".mcap")
    assert (folder / "metadata.yaml").is_file() and (folder / "bag.mcap").is_file()
    sc = load_scenario("office")
    msgs = read_bag(folder)
    names = check_common(tabs, msgs, sc.dt)
    assert names == ["mcl", "dead_reckoning"]
    # /map: the scenario's occupancy grid, nav_msgs' cell values and layout
    [(ns, kind, grid)] = msgs["/map"]
    assert kind == "nav_msgs/msg/OccupancyGrid" and ns == 0
    cells = sc.world.grid.cells
    assert (grid.info.width, grid.info.height) == (cells.shape[1], cells.shape[0])
    assert grid.info.resolution == pytest.approx(sc.world.grid.resolution, rel=1e-6)  # float32 in ROS
    np.testing.assert_array_equal(grid.data, cells.reshape(-1))
    # /scan/laser: one LaserScan per scan; each reading at its beam, ranges as float32
    rd = tabs["readings"]
    spec = next(s for s in sc.sensors if s.name == "laser")
    beams = beam_angles(spec.n_beams, spec.fov)
    scans = msgs["/scan/laser"]
    ticks = sorted(set(rd["tick"].tolist()))
    assert len(scans) == len(ticks) > 0
    for k, (ns, kind, m) in zip(ticks, scans, strict=True):
        assert kind == "sensor_msgs/msg/LaserScan" and ns == k * round(sc.dt * 1e9)
        assert m.header.frame_id == "base_link" and m.range_max == pytest.approx(spec.max_range)
        rows = np.flatnonzero(rd["tick"] == k)
        angles = m.angle_min + m.angle_increment * np.arange(len(m.ranges))
        np.testing.assert_allclose(angles, beams, atol=1e-6)  # float32 fields
        idx = [int(np.argmin(np.abs(np.remainder(beams - b + np.pi, 2 * np.pi) - np.pi)))
               for b in rd["bearing_rad"][rows]]
        np.testing.assert_array_equal(m.ranges[idx], rd["range_m"][rows].astype(np.float32))
        assert np.isnan(np.delete(m.ranges, idx)).all()


def test_slam_loop_bag_equals_the_tables_sqlite(tmp_path):
    tabs, folder = export_both(tmp_path, "slam_loop", 8.0, ".db3")
    assert (folder / "bag.db3").is_file()
    sc = load_scenario("slam_loop")
    msgs = read_bag(folder)
    assert set(check_common(tabs, msgs, sc.dt)) == set(sc.default_filters)
    [(_, kind, beacons)] = msgs["/beacons"]
    assert kind == "visualization_msgs/msg/MarkerArray"
    assert [(mk.id, mk.pose.position.x, mk.pose.position.y) for mk in beacons.markers] == \
        [(b.id, b.x, b.y) for b in sc.world.beacons]
    assert "/map" not in msgs and not any(t.startswith("/scan") for t in msgs)


def test_bad_ros2_names(tmp_path, capsys):
    assert main(["export", "default", "--duration", "1", "--out", str(tmp_path / "x.npz"), "--ros2"]) == 2
    assert "with --ros2, expected run.mcap or run.db3" in capsys.readouterr().err
    assert main(["export", "default", "--duration", "1", "--out", str(tmp_path / "x.db3")]) == 2
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "mine.txt").write_text("keep")
    assert main(["export", "default", "--duration", "1", "--out", str(tmp_path / "x.mcap"), "--ros2"]) == 2
    assert "not a ROS 2 bag folder" in capsys.readouterr().err
    assert (tmp_path / "x" / "mine.txt").read_text() == "keep"


def test_a_bag_is_replaced_whole(tmp_path):
    out = tmp_path / "run.mcap"
    for seconds in ("1", "2"):
        assert main(["export", "default", "--duration", seconds, "--out", str(out), "--ros2"]) == 0
    truth = read_bag(tmp_path / "run")["/truth"]
    assert len(truth) == round(2.0 / load_scenario("default").dt) + 1  # the second run's
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
