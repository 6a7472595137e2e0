"""ropes.sim: the simulator from Python (ropes._sim). Witnesses: forward kinematics against
a separate numpy implementation of the URDF's joint chain; generated datasets against
ropes-generate's bytes; rendered images against the dataset's rows."""
import json
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import ropes
from ropes import dataset, sim

GENERATE = os.environ.get("ROPES_GENERATE_EXE") or shutil.which("ropes-generate")


def _rpy(r, p, y):
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _axis_angle(axis, angle):
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def _numpy_fk(urdf, q_by_joint):
    """Each link's 4x4 pose in the root link's frame, from the URDF text alone."""
    root = ET.parse(urdf).getroot()
    children = {}
    for j in root.findall("joint"):
        children.setdefault(j.find("parent").get("link"), []).append(j)
    child_links = {j.find("child").get("link") for j in root.findall("joint")}
    base = [l.get("name") for l in root.findall("link") if l.get("name") not in child_links][0]
    poses = {base: np.eye(4)}
    stack = [base]
    while stack:
        parent = stack.pop()
        for j in children.get(parent, []):
            o = j.find("origin")
            xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
            rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = _rpy(*rpy), xyz
            M = np.eye(4)
            if j.get("type") in ("revolute", "continuous"):
                axis = [float(v) for v in j.find("axis").get("xyz").split()]
                M[:3, :3] = _axis_angle(axis, q_by_joint[j.get("name")])
            elif j.get("type") == "prismatic":
                axis = np.array([float(v) for v in j.find("axis").get("xyz").split()])
                M[:3, 3] = axis / np.linalg.norm(axis) * q_by_joint[j.get("name")]
            child = j.find("child").get("link")
            poses[child] = poses[parent] @ T @ M
            stack.append(child)
    return poses


@pytest.fixture(scope="module")
def tiny():
    return sim.DatasetConfig.load("tiny-1c")


def test_forward_kinematics_matches_a_numpy_chain_of_the_urdf(tiny):
    robot = sim.Robot(tiny.robot)
    assert robot.joints[:7] == [f"panda_joint{i}" for i in range(1, 8)]
    assert robot.limits.shape == (len(robot.joints), 2)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, len(robot.joints))
        ours = robot.link_poses(q)
        witness = _numpy_fk(tiny.robot, dict(zip(robot.joints, q)))
        assert set(ours) == set(witness)
        for link, pose in ours.items():
            np.testing.assert_allclose(pose, witness[link], atol=1e-12, err_msg=link)


def test_generated_dataset_is_ropes_generates_bytes_and_the_rig_renders_its_rows(tmp_path, tiny):
    calls = []
    r = sim.generate_dataset(tiny, tmp_path / "py", seed=5, threads=2,
                             progress=lambda done, total, message: calls.append((done, total)))
    assert r.complete and r.shards_written == 1 and not r.stopped
    assert calls == [(1, 1)]
    subprocess.run([GENERATE, "--config", "tiny-1c", "--seed", "5", "--out",
                    str(tmp_path / "cpp")], check=True, capture_output=True)
    for name in ("manifest.json", "shards/images-00000.npy", "shards/angles-00000.npy"):
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cpp" / name).read_bytes()
    d = dataset.Dataset(tmp_path / "py")
    rig = sim.Rig(tiny)
    assert rig.joint_names == d.metadata["joint_names"]
    assert rig.image_shape == d.columns["images"].row_shape
    rows = [0, 7, 33]
    angles = d.take("angles", rows)
    np.testing.assert_array_equal(rig.render(angles), d.take("images", rows))
    np.testing.assert_array_equal(rig.render(angles[1]), d.take("images", [7])[0])
    masks = rig.robot_masks(angles)
    assert set(np.unique(masks)) <= {0, 255} and (masks == 255).any()


def _sharded_config(tmp_path, tiny):
    spec = json.loads(open(tiny.file).read())
    base = os.path.dirname(tiny.file)
    spec["distribution"] = os.path.normpath(os.path.join(base, spec["distribution"]))
    spec["robot"] = os.path.normpath(os.path.join(base, spec["robot"]))
    spec["anchors_per_shard"] = 10
    spec.pop("source", None)
    path = tmp_path / "sharded.json"
    path.write_text(json.dumps(spec))
    return path


def test_a_progress_callback_stops_generation_and_a_second_call_resumes(tmp_path, tiny):
    config = _sharded_config(tmp_path, tiny)
    r = sim.generate_dataset(config, tmp_path / "a", seed=1, progress=lambda *a: False)
    assert r.stopped and not r.complete and r.shards_written == 1
    assert not (tmp_path / "a" / "manifest.json").exists()
    r = sim.generate_dataset(config, tmp_path / "a", seed=1)
    assert r.complete and r.shards_written == 3 and r.shards_skipped == 1
    sim.generate_dataset(config, tmp_path / "b", seed=1)
    assert (tmp_path / "a" / "manifest.json").read_bytes() == \
        (tmp_path / "b" / "manifest.json").read_bytes()

    class Boom(Exception):
        pass

    def boom(done, total, message):
        raise Boom(message)

    with pytest.raises(Boom, match="shard 0"):
        sim.generate_dataset(config, tmp_path / "c", seed=1, progress=boom)


def test_bad_input_is_one_clear_error(tmp_path, tiny):
    with pytest.raises(ropes.ConfigError, match="'no-such-config' is neither a file nor"):
        sim.DatasetConfig.load("no-such-config")
    with pytest.raises(ropes.errors.ModelError, match="missing.urdf"):
        sim.Robot(tmp_path / "missing.urdf")
    robot = sim.Robot(tiny.robot)
    with pytest.raises(ropes.ShapeError,
                       match=rf"q: expected a float64 array of shape \[{len(robot.joints)}\], "
                             r"got a float64 array of shape \[3\]"):
        robot.forward_kinematics([0.0, 1.0, 2.0])
    rig = sim.Rig(tiny)
    with pytest.raises(ropes.ShapeError, match=r"q: expected a float64 array of shape \[n, 7\], got a float64 array of shape \[2, 4\]"):
        rig.render(np.zeros((2, 4)))
    with pytest.raises(ropes.ShapeError, match="expected real numbers"):
        rig.render(np.array(["a", "b", "c"]))
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"name": "bad", "anchors": 0}))
    with pytest.raises(ropes.ConfigError, match="bad.json"):
        sim.DatasetConfig.load(bad)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "mine.txt").write_text("keep")
    with pytest.raises(RuntimeError, match="full"):
        sim.generate_dataset(tiny, tmp_path / "full")
    assert [p.name for p in (tmp_path / "full").iterdir()] == ["mine.txt"]


def _config_with(tmp_path, tiny, name="changed", **changes):
    """tiny-1c with its paths made absolute and `changes` applied, written to tmp_path."""
    spec = json.loads(open(tiny.file).read())
    base = os.path.dirname(tiny.file)
    for key in ("distribution", "robot"):
        spec[key] = os.path.normpath(os.path.join(base, spec[key]))
    spec.pop("source", None)
    spec.update(changes)
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(spec))
    return path


def test_rig_files_and_the_framing_check_name_the_link_and_the_pose(tmp_path, tiny):
    reach = sim.check_framing(tiny)
    assert [r["camera"] for r in reach] == ["cam0"] and 0 < reach[0]["reach"] < 1
    assert tiny.to_dict()["rig"]["name"] == "single_camera"  # the installed rig file
    # a rig file beside the config, so close that the arm leaves the image
    rig = {"name": "close", "cameras": [{"name": "near_cam", "target": [-0.6, 0.0, 0.62],
                                         "distance": 0.6, "pitch_deg": -30.0,
                                         "fov_y_deg": 40.0}]}
    (tmp_path / "close_rig.json").write_text(json.dumps(rig))
    close = _config_with(tmp_path, tiny, rig="close_rig.json")
    assert sim.DatasetConfig.load(close).to_dict()["rig"]["cameras"][0]["name"] == "near_cam"
    pattern = (r"rig 'close' camera 'near_cam' loses link '\w+' from view: at anchor \d+, "
               r"regime [^ ]+ \(panda_joint1 -?\d\.\d{3}, .*panda_joint7 -?\d\.\d{3}, seed 0\) "
               r"its origin lands at \(-?\d\.\d{3}, -?\d\.\d{3}\) in normalised image coordinates, "
               r"\d+\.\d px outside the image")
    with pytest.raises(ropes.ConfigError, match=pattern):
        sim.check_framing(close)
    with pytest.raises(ropes.ConfigError, match="loses link"):
        sim.generate_dataset(close, tmp_path / "out")
    assert not (tmp_path / "out").exists()
    with pytest.raises(ropes.ConfigError,
                       match=r"rig is \"nowhere\"; expected the name of an installed rig "
                             r"\(single_camera, two_cameras in "):
        sim.DatasetConfig.load(_config_with(tmp_path, tiny, name="bad_rig", rig="nowhere"))
    with pytest.raises(ropes.ConfigError, match="missing_rig.json"):
        sim.DatasetConfig.load(_config_with(tmp_path, tiny, name="no_rig", rig="missing_rig.json"))


def test_the_distribution_names_every_joint_of_the_urdf_and_no_other(tmp_path, tiny):
    dist = json.loads(open(tiny.distribution).read())
    extra = dict(dist, joints=dist["joints"] + ["panda_finger"],
                 held=dict(dist["held"], panda_finger=0.0))
    (tmp_path / "extra.json").write_text(json.dumps(extra))
    config = _config_with(tmp_path, tiny, name="extra_config",
                          distribution=str(tmp_path / "extra.json"))
    with pytest.raises(ropes.ConfigError,
                       match=r"joint 'panda_finger' is not a movable joint of robot "
                             r"'ropes_panda' \(.*panda.urdf\), whose movable joints are "
                             r"panda_joint1, panda_joint2, .*panda_joint7"):
        sim.generate_dataset(config, tmp_path / "out")
    held = dict(dist["held"])
    del held["panda_joint7"]
    fewer = dict(dist, joints=dist["joints"][:6], held=held)
    (tmp_path / "fewer.json").write_text(json.dumps(fewer))
    config = _config_with(tmp_path, tiny, name="fewer_config",
                          distribution=str(tmp_path / "fewer.json"))
    with pytest.raises(ropes.ConfigError,
                       match=r"movable joint 'panda_joint7' of robot 'ropes_panda' is not in "
                             r"the distribution .*fewer.json"):
        sim.Rig(config)
    with pytest.raises(ropes.ConfigError, match="panda_joint7"):
        sim.generate_dataset(config, tmp_path / "out")
    assert not (tmp_path / "out").exists()
