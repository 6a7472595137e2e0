"""The simulator (ropes_sim) from Python: a URDF's forward kinematics, a dataset config's
camera rig rendered to numpy arrays, and datasets generated as ropes-generate makes them
(the same bytes for the same config and seed).

    >>> robot = ropes.sim.Robot("panda.urdf")
    >>> poses = robot.forward_kinematics(np.zeros(len(robot.joints)))   # [links, 4, 4]
    >>> config = ropes.sim.DatasetConfig.load("tiny-1c")              # installed, or a file
    >>> rig = ropes.sim.Rig(config)
    >>> images = rig.render(np.zeros((5, len(rig.joint_names))))        # [5, cams, H, W] uint8
    >>> ropes.sim.generate_dataset(config, "data", seed=0, progress=print)
"""
import collections
import os

import numpy as np

from . import _sim
from .errors import ShapeError, check_callback

DatasetConfig = _sim.DatasetConfig
DatasetConfig.__doc__ = """A dataset config (ropes_sim/dataset_config.hpp): the robot's URDF,
the distribution of its joints, the camera rig and the counts. DatasetConfig.load(name_or_path)
reads a file or an installed config by name; ropes.ConfigError names the file, the field, the
value and what was expected."""

GenerateResult = collections.namedtuple(
    "GenerateResult", ["shards_written", "shards_skipped", "complete", "images", "warnings",
                       "stopped"])


def _angles(q, what):
    a = np.asarray(q)
    if a.dtype.kind not in "fiu":
        raise ShapeError(f"{what}: expected real numbers (a float64 array), got a {a.dtype} "
                         f"array of shape {list(a.shape)}")
    return np.ascontiguousarray(a, dtype=np.float64)


def _config(config):
    if isinstance(config, DatasetConfig):
        return config
    return DatasetConfig.load(os.fspath(config))


class Robot:
    """A URDF's links and joints, with forward kinematics on Simbody. ropes.errors.ModelError
    names the file when it cannot be read or has a joint type the workspace does not support."""

    def __init__(self, urdf):
        self._robot = _sim.Robot(os.fspath(urdf))

    @property
    def name(self):
        return self._robot.name

    @property
    def links(self):
        """Link names, parents first (the root is link 0)."""
        return self._robot.links

    @property
    def joints(self):
        """The movable joints' names: the robot's coordinates, in order."""
        return self._robot.joints

    @property
    def limits(self):
        """[joints, 2]: each movable joint's lower and upper limit (radians or metres)."""
        return self._robot.limits

    def forward_kinematics(self, q):
        """X_WL, each link's pose in the root link's frame, for coordinates `q` (one per
        joint): a float64 array [links, 4, 4]. ropes.ShapeError for another shape."""
        return self._robot.forward_kinematics(_angles(q, "q"))

    def link_poses(self, q):
        """forward_kinematics(q) as {link name: 4x4 array}."""
        return dict(zip(self.links, self.forward_kinematics(q)))

    def __repr__(self):
        return f"Robot({self.name!r}, joints={self.joints})"


class Rig:
    """A dataset config's robot seen by its camera rig: the images of a dataset row for the
    given angles of the config's distribution joints (every movable joint of the URDF), as
    ropes-generate renders them. Owns an OSMesa context: use it on the thread that made it."""

    def __init__(self, config):
        self._rig = _sim.RigRenderer(_config(config))

    @property
    def joint_names(self):
        return self._rig.joint_names

    @property
    def camera_names(self):
        return self._rig.camera_names

    @property
    def image_shape(self):
        """(cameras, height, width)"""
        return (self._rig.cameras, self._rig.height, self._rig.width)

    def render(self, q):
        """q [joints] -> uint8 [cameras, H, W]; q [n, joints] -> [n, cameras, H, W]. The GIL
        is released while it renders."""
        a = _angles(q, "q")
        if a.ndim == 1:
            return self._rig.render(a[None, :])[0]
        return self._rig.render(a)

    def robot_masks(self, q):
        """The robot's silhouette in each camera (255 on the robot, nothing hiding it), laid
        out as render()'s images."""
        a = _angles(q, "q")
        if a.ndim == 1:
            return self._rig.robot_masks(a[None, :])[0]
        return self._rig.robot_masks(a)


def generate_dataset(config, out, seed=0, threads=1, shard_index=0, shard_count=1,
                     progress=None):
    """Generates (or resumes) the dataset of `config` (a DatasetConfig, a file or an
    installed name) into `out`: the bytes ropes-generate writes for the same config and seed,
    whatever `threads`. `progress(done, total, message)` is called after each shard; when it
    returns False, generation stops after that shard (GenerateResult.stopped; calling again
    resumes), and what it raises (KeyboardInterrupt included) stops it and is raised here.
    Errors name the directory, the config field or the camera, before anything is written."""
    check_callback(progress, "progress")
    r = _sim.generate_dataset(_config(config), os.fspath(out), seed, threads, shard_index,
                              shard_count, progress)
    return GenerateResult(**r)


def check_framing(config, seed=0):
    """The framing check of a config's rig: per camera, the link origin that reaches furthest
    from the image's centre over every sample of the config's anchors, as a list of dicts
    (camera, link, anchor, regime, angles, x, y in normalised image coordinates, reach: 1 is
    the image's edge, beyond_pixels: how far past it). Raises ropes.ConfigError naming the
    camera, the link and the pose when one lands more than a pixel past the edge
    (generate_dataset refuses such a config too)."""
    config = _config(config)
    reach = _sim.framing_reach(config, seed)
    _sim.check_framing(config, seed)
    return reach


def preview_extremes(config, png, seed=0, scale=2):
    """The framing check of a config's rig (ropes-generate --preview-extremes): for each
    camera, the samples whose link origins reach furthest left, right, up and down, as a PNG
    contact sheet."""
    _sim.write_extremes_preview(_config(config), seed, os.fspath(png), scale)


def tune_malloc_for_rendering():
    """glibc's allocator tuned for rendering large meshes (ropes_sim/renderer.hpp):
    process-wide, what ropes-generate does at start."""
    _sim.tune_malloc_for_rendering()
