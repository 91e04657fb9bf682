"""sparseloop_node against `sparseloop run`, for real: a roscore of its own on a free loopback port,
a bag written from the CLI tests' rendered sequence (images, camera_info, raw poses) played at 5x
real time, the node's topics read by this process (rospy). Everything started here is stopped here.

Environment (set by CTest): SPARSELOOP_CLI, SPARSELOOP_NODE, PYTHONPATH with the build tree's
sparseloop module (images and trajectories are read with it).
"""
import csv
import json
import os
import pathlib
import signal
import socket
import subprocess
import tempfile
import time

import numpy as np
import pytest

import sparseloop

IMAGE, INFO, POSE = "/cam0/image_raw", "/cam0/camera_info", "/vslam/pose"


def require(var):
    path = os.environ.get(var)
    if not path or not os.path.exists(path):
        pytest.fail(f"{var} must name the built binary (got {path!r})")
    return path


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def quaternion_xyzw(r):
    """Rotation matrix -> unit quaternion (x, y, z, w)."""
    t = np.trace(r)
    if t > 0:
        s = 2.0 * np.sqrt(t + 1.0)
        return np.array([(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s,
                         (r[1, 0] - r[0, 1]) / s, 0.25 * s])
    i = int(np.argmax(np.diag(r)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
    q = np.zeros(4)
    q[i] = 0.25 * s
    q[j] = (r[j, i] + r[i, j]) / s
    q[k] = (r[k, i] + r[i, k]) / s
    q[3] = (r[k, j] - r[j, k]) / s
    return q


def run_loops(out):
    """Detected loops (query, match) and the accepted ones of a `run --out` folder."""
    with open(out / "loops.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["status"] == "detected"]
    return ({(int(r["query"]), int(r["match"])) for r in rows},
            {(int(r["query"]), int(r["match"])) for r in rows if r["accepted"] == "1"})


class Sequence:
    """A rendered 60-frame aerial flight (2 laps): frames, stamps, intrinsics, raw poses, and
    `run`'s output on it."""

    def __init__(self, root, cli, plan="circuit", seed=1, drift=1.0):
        self.root, self.cli = root, cli
        self.seq = root / f"seq_{plan}_{seed}_{drift}"
        subprocess.run([cli, "render", "--world", "aerial", "--plan", plan, "--frames", "60",
                        "--laps", "2", "--seed", str(seed), "--drift", str(drift), "--out",
                        str(self.seq)], check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        self.stamps = [float(x) for x in (self.seq / "times.txt").read_text().split()]
        p0 = (self.seq / "calib.txt").read_text().splitlines()[0].split()[1:]
        self.fx, self.cx, self.fy, self.cy = float(p0[0]), float(p0[2]), float(p0[5]), float(p0[6])
        self.images = sorted((self.seq / "image_0").glob("*.png"))
        self.raw = sparseloop.read_trajectory(str(self.seq / "poses_raw.txt"), "kitti")["poses"]
        assert len(self.images) == len(self.stamps) == len(self.raw) == 60
        # `run` without the render's mapped pixels: the bag has none.
        config = root / "no_mapped.json"
        config.write_text('{"use_mapped_pixels": false}')
        self.run_out = self.seq.with_name(self.seq.name + "_run")
        self.run(self.run_out, "--config", str(config))
        self.run_loops, self.run_accepted = run_loops(self.run_out)
        traj = sparseloop.read_trajectory(str(self.run_out / "trajectory_kitti.txt"), "kitti")
        self.run_positions = traj["poses"][:, :3, 3]
        self._run_mapped_loops = None

    def run(self, out, *args):
        subprocess.run([self.cli, "run", "--dataset", f"kitti:{self.seq}", "--poses",
                        str(self.seq / "poses_raw.txt"), "--out", str(out), *args], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)

    @property
    def run_mapped_loops(self):
        """`run`'s loops with the render's mapped/ pixels (the node gets them as PointCloud2)."""
        if self._run_mapped_loops is None:
            out = self.seq.with_name(self.seq.name + "_run_mapped")
            self.run(out)
            self._run_mapped_loops = run_loops(out)[0]
        return self._run_mapped_loops

    def mapped(self, i):
        px, depths = sparseloop.read_mapped_pixels(str(self.seq / "mapped" / f"{i:06d}.txt"))
        return np.asarray(px), np.asarray(depths)

    def frame_of(self, stamp):
        i = int(np.argmin(np.abs(np.array(self.stamps) - stamp)))
        assert abs(self.stamps[i] - stamp) < 1e-6, stamp
        return i

    def image_msg(self, i, stamp=None):
        from sensor_msgs.msg import Image
        import rospy
        img = sparseloop.read_image(str(self.images[i]))
        m = Image()
        m.header.stamp = rospy.Time.from_sec(self.stamps[i] if stamp is None else stamp)
        m.header.frame_id = "cam0"
        m.height, m.width = img.shape
        m.encoding = "mono8"
        m.step = img.shape[1]
        m.data = img.tobytes()
        return m

    def info_msg(self):
        from sensor_msgs.msg import CameraInfo
        import rospy
        m = CameraInfo()
        m.header.stamp = rospy.Time.from_sec(self.stamps[0])
        m.width, m.height = 640, 480
        m.distortion_model = "plumb_bob"
        m.D = [0.0] * 5
        m.K = [self.fx, 0, self.cx, 0, self.fy, self.cy, 0, 0, 1]
        return m

    def pose_msg(self, i, offset=0.0):
        from geometry_msgs.msg import PoseStamped
        import rospy
        m = PoseStamped()
        m.header.stamp = rospy.Time.from_sec(self.stamps[i] + offset)
        m.header.frame_id = "world"
        t, q = self.raw[i][:3, 3], quaternion_xyzw(self.raw[i][:3, :3])
        m.pose.position.x, m.pose.position.y, m.pose.position.z = t
        (m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
         m.pose.orientation.w) = q
        return m

    def write_bag(self, path):
        import rosbag
        import rospy
        with rosbag.Bag(str(path), "w") as bag:
            for i in range(len(self.stamps)):
                t = rospy.Time.from_sec(self.stamps[i] + 1.0)  # a bag refuses record time 0
                if i == 0:
                    bag.write(INFO, self.info_msg(), t)
                bag.write(POSE, self.pose_msg(i), t)
                bag.write(IMAGE, self.image_msg(i), t)


class Ros:
    """roscore on a free loopback port; this process as a rospy node; started processes."""

    def __init__(self, root):
        self.port = free_port()
        self.env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{self.port}",
                        ROS_HOSTNAME="127.0.0.1", ROS_IP="127.0.0.1", ROS_HOME=str(root / "ros"),
                        ROS_LOG_DIR=str(root / "ros" / "log"))
        os.environ.update({k: self.env[k] for k in ("ROS_MASTER_URI", "ROS_HOSTNAME", "ROS_IP",
                                                    "ROS_HOME", "ROS_LOG_DIR")})
        self.procs = []
        self.core = self.start(["roscore", "-p", str(self.port)], "roscore")
        import rosgraph
        master = rosgraph.Master("/sparseloop_test")
        deadline = time.time() + 30
        while True:
            try:
                master.getPid()
                break
            except Exception:
                if time.time() > deadline or self.core.poll() is not None:
                    raise RuntimeError(f"roscore did not come up on port {self.port}")
                time.sleep(0.2)
        import rospy
        rospy.init_node("sparseloop_test", anonymous=True, disable_signals=True)

    def start(self, cmd, name):
        home = pathlib.Path(self.env["ROS_HOME"])
        home.mkdir(parents=True, exist_ok=True)
        log = open(home / f"{name}.log", "a")
        p = subprocess.Popen(cmd, env=self.env, stdout=log, stderr=subprocess.STDOUT,
                             start_new_session=True)
        p.log_path = log.name
        self.procs.append(p)
        return p

    @staticmethod
    def stop(p, timeout=20):
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGINT)
            try:
                p.wait(timeout)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        return p.returncode

    def close(self):
        import rospy
        rospy.signal_shutdown("test done")
        for p in reversed(self.procs):
            self.stop(p)


@pytest.fixture(scope="module")
def sequence():
    with tempfile.TemporaryDirectory(prefix="sparseloop_ros_") as d:
        yield Sequence(pathlib.Path(d), require("SPARSELOOP_CLI"))


@pytest.fixture(scope="module")
def ros(sequence):
    r = Ros(sequence.root)
    yield r
    r.close()
    assert all(p.poll() is not None for p in r.procs)


class NodeRun:
    """One sparseloop_node (name /sparseloop) and what it publishes."""

    def __init__(self, ros, root, params, image_topic=IMAGE, pose_topic=POSE, compressed=False):
        import rospy
        from nav_msgs.msg import Path
        from std_msgs.msg import Float64MultiArray
        from visualization_msgs.msg import MarkerArray
        from diagnostic_msgs.msg import DiagnosticArray
        self.ros = ros
        self.loops, self.paths, self.markers, self.diag = [], [], [], {}
        if rospy.has_param("/sparseloop"):
            rospy.delete_param("/sparseloop")
        for k, v in params.items():
            rospy.set_param("/sparseloop/" + k, v)
        self.subs = [
            rospy.Subscriber("/sparseloop/loops", Float64MultiArray, self.loops.append),
            rospy.Subscriber("/sparseloop/path", Path, self.paths.append),
            rospy.Subscriber("/sparseloop/markers", MarkerArray, self.markers.append),
            rospy.Subscriber("/diagnostics", DiagnosticArray, self.on_diag)]
        self.inputs = {image_topic + ("/compressed" if compressed else ""), INFO} | (
            {pose_topic} if pose_topic else set())
        self.proc = ros.start([require("SPARSELOOP_NODE"), "__name:=sparseloop",
                               f"image:={image_topic}", f"camera_info:={INFO}",
                               f"pose:={pose_topic or POSE}", "mapped_points:=/mapped_points"],
                              "node")
        wait_for(lambda: self.subs[0].get_num_connections() > 0 and self.subscribed(),
                 30, "the node to subscribe and publish", self.proc)

    def subscribed(self):
        import rosgraph
        _, subscribers, _ = rosgraph.Master("/sparseloop_test").getSystemState()
        have = {t for t, nodes in subscribers if "/sparseloop" in nodes}
        return self.inputs <= have

    def on_diag(self, msg):
        for s in msg.status:
            if s.name == "/sparseloop":
                self.diag = {kv.key: float(kv.value) for kv in s.values}

    def finish(self):
        import rospy
        from std_srvs.srv import Trigger
        rospy.wait_for_service("/sparseloop/finish", 10)
        r = rospy.ServiceProxy("/sparseloop/finish", Trigger)()
        assert r.success, r.message
        summary = json.loads(r.message)
        # Every detected loop was published before finish returned; topics are not ordered with
        # the service reply, so the last ones may still be on their way.
        wait_for(lambda: len(self.loops) >= len(summary["loops"]), 10,
                 f"{len(summary['loops'])} loop messages", self.proc)
        return summary

    def close(self):
        for s in self.subs:
            s.unregister()
        code = Ros.stop(self.proc)
        assert code == 0, pathlib.Path(self.proc.log_path).read_text()[-3000:]


def connect(run, publishers, info_msg):
    """Waits until the node subscribed to every publisher, then publishes camera_info (latched)."""
    wait_for(lambda: all(p.get_num_connections() > 0 for p in publishers.values()), 30,
             "the node to connect", run.proc)
    publishers["info"].publish(info_msg)


def unregister(publishers):
    for p in publishers.values():
        p.unregister()


def wait_for(condition, timeout, what, proc=None):
    deadline = time.time() + timeout
    while not condition():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"waiting for {what}: the node exited with {proc.returncode}: "
                                 + pathlib.Path(proc.log_path).read_text()[-3000:])
        if time.time() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


def last_with_positions(messages, positions, xyz_of):
    """The last of `messages` whose positions (xyz_of(message), n x 3) are `positions` (1e-6), or
    None: a path and its markers belong to one solve, and a solve during the run can have as many
    keyframes as the final one."""
    for m in reversed(messages):
        xyz = xyz_of(m)
        if xyz.shape == positions.shape and np.abs(xyz - positions).max() < 1e-6:
            return m
    return None


def path_xyz(path):
    return np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z]
                     for p in path.poses]).reshape(-1, 3)


def keyframe_strip_xyz(markers):
    strip = [m for m in markers.markers if m.ns == "keyframes"][0]
    return np.array([[p.x, p.y, p.z] for p in strip.points]).reshape(-1, 3)


def loop_pairs(run, sequence):
    pairs = set()
    for m in run.loops:
        assert [d.label for d in m.layout.dim][0] == "loop"
        assert len(m.data) == 16
        pairs.add((sequence.frame_of(m.data[0]), sequence.frame_of(m.data[1])))
    return pairs


@pytest.fixture(scope="module")
def figure8(sequence):
    """A second flight over another world (seed 2): a figure-8 at three times the default drift
    (raw Sim(3) ATE 17.6, 30 loops, 16 accepted)."""
    return Sequence(sequence.root, require("SPARSELOOP_CLI"), plan="figure8", seed=2, drift=3.0)


@pytest.mark.parametrize("flight", ["circuit", "figure8"])
@pytest.mark.parametrize("solve_while_running", [False, True])
def test_node_on_a_played_bag_matches_run(ros, request, flight, solve_while_running):
    sequence = request.getfixturevalue("sequence" if flight == "circuit" else "figure8")
    bag = sequence.seq.with_name(sequence.seq.name + ".bag")
    if not bag.exists():
        sequence.write_bag(bag)
    traj_file = sequence.root / f"node_traj_{flight}_{solve_while_running}.txt"
    run = NodeRun(ros, sequence.root, {
        "config": {"use_mapped_pixels": False}, "solve_while_running": solve_while_running,
        "trajectory_file": str(traj_file), "loops_file": str(sequence.root / "node_loops.csv")})
    try:
        # Each topic waits for its subscriber (the node), so no first message is lost.
        play = ros.start(["rosbag", "play", "--wait-for-subscribers", "-d", "0.5", "-r", "5",
                          "--quiet", str(bag)], "play")
        assert play.wait(120) == 0
        # Every image reached the node before it is told to finish.
        wait_for(lambda: run.diag.get("images", 0) >= 60, 30, "60 images at the node", run.proc)
        summary = run.finish()
        # The final solve's path and markers, published before finish returned (their positions
        # are the trajectory file's, written from the same solve); a solve while the bag played
        # can have all 60 keyframes too, and its markers may be the last ones received so far.
        final = sparseloop.read_trajectory(str(traj_file), "tum")["poses"][:, :3, 3]
        wait_for(lambda: last_with_positions(run.paths, final, path_xyz) is not None, 10,
                 "the final path")
        wait_for(lambda: last_with_positions(run.markers, final, keyframe_strip_xyz) is not None,
                 10, "the final path's markers")
    finally:
        run.close()
    assert summary["keyframes"] == 60 and summary["keyframes_without_pose"] == 0, summary
    assert summary["dropped_out_of_order"] == 0 and summary["dropped_bad"] == 0, summary
    # The same loops as `run`, published as they were detected.
    assert sequence.run_loops, "the rendered circuit has loops"
    assert loop_pairs(run, sequence) == sequence.run_loops
    accepted = {(l["query"], l["match"]) for l in summary["loops"] if l["accepted"]}
    assert accepted == sequence.run_accepted
    # The corrected path: run's trajectory (one solve at the end: to 1e-6 m; solved while the
    # bag plays: the final solve starts from earlier corrections, to 0.05 m).
    path = last_with_positions(run.paths, final, path_xyz)
    xyz = path_xyz(path)
    stamps = [p.header.stamp.to_sec() for p in path.poses]
    assert [sequence.frame_of(s) for s in stamps] == list(range(60))
    # Solved while running, the final solve starts from the previous estimate and Ceres stops at
    # a relative cost decrease: the two minima agree to a fraction of the correction. 0.05 m, or
    # 0.2 % of run's largest correction where that is larger (figure-8: 0.058 m of 52.6 m).
    run_moved = np.linalg.norm(sequence.run_positions - sequence.raw[:, :3, 3], axis=1).max()
    tol = max(0.05, 0.002 * run_moved) if solve_while_running else 1e-6
    err = np.linalg.norm(xyz - sequence.run_positions, axis=1).max()
    assert err < tol, (err, tol)
    moved = np.linalg.norm(xyz - sequence.raw[:, :3, 3], axis=1).max()
    assert moved > 10 * tol, "the loops corrected the raw trajectory"
    # The trajectory file (TUM) is the path; markers draw the kept loops.
    written = sparseloop.read_trajectory(str(traj_file), "tum")
    assert np.abs(written["poses"][:, :3, 3] - xyz).max() < 1e-6
    markers = last_with_positions(run.markers, final, keyframe_strip_xyz)
    loops_marker = [m for m in markers.markers if m.ns == "loops"][0]
    assert len(loops_marker.points) == 2 * len(accepted)


def test_node_survives_lost_tracking_and_out_of_order_stamps(ros, sequence):
    import rospy
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import CameraInfo, Image
    run = NodeRun(ros, sequence.root, {"config": {"use_mapped_pixels": False}})
    pubs = {"image": rospy.Publisher(IMAGE, Image, queue_size=100),
            "info": rospy.Publisher(INFO, CameraInfo, queue_size=10, latch=True),
            "pose": rospy.Publisher(POSE, PoseStamped, queue_size=100)}
    try:
        connect(run, pubs, sequence.info_msg())
        for i in range(40):
            if i in (31, 34):
                continue  # 31 comes late (below), 34 before 33
            if i == 33:  # images out of order, both still waiting for their poses: reordered
                pubs["image"].publish(sequence.image_msg(34))
                pubs["image"].publish(sequence.image_msg(33))
                pubs["pose"].publish(sequence.pose_msg(33))
                pubs["pose"].publish(sequence.pose_msg(34))
                continue
            if not 15 <= i < 25:  # tracking lost: no pose for frames 15-24
                pubs["pose"].publish(sequence.pose_msg(i))
            pubs["image"].publish(sequence.image_msg(i))
            time.sleep(0.02)
        wait_for(lambda: run.diag.get("keyframes", 0) >= 39, 60, "39 keyframes", run.proc)
        # Too late to be used: 31 after 39 was taken, and 32 again.
        pubs["image"].publish(sequence.image_msg(31))
        pubs["image"].publish(sequence.image_msg(32))
        wait_for(lambda: run.diag.get("images", 0) >= 41, 30, "41 images", run.proc)
        summary = run.finish()
        assert run.proc.poll() is None, "the node is alive after the gap"
    finally:
        unregister(pubs)
        run.close()
    assert summary["images"] == 41, summary
    assert summary["dropped_out_of_order"] == 2, summary
    assert summary["keyframes"] == 39, summary
    assert summary["keyframes_without_pose"] == 10, summary
    assert summary["path_keyframes"] == 29, summary  # only keyframes with a pose are in the graph


@pytest.mark.parametrize("params,message", [
    ({"pose_typo": "x"}, "unknown parameter /sparseloop/pose_typo"),
    ({"pose_type": "imu"}, "must be pose, pose_cov, odometry or tf, got 'imu'"),
    ({"config": {"detector": {"nope": 1}}}, "detector.nope"),
    ({"max_pose_dt": -1.0}, "~max_pose_dt must be > 0 s"),
    ({"diagnostics_period": -5.0}, "/sparseloop/diagnostics_period must be in [0, 3600] s"),
    ({"image_queue": 3000000000.0},
     "/sparseloop/image_queue must be an integer in [1, 100000], got 3000000000"),
    ({"trajectory_file": "/nonexistent_folder/t.txt"},
     "~trajectory_file /nonexistent_folder/t.txt: expected an existing, writable output directory"),
    ({"preset": "tiny"}, "~preset tiny: expected a preset name (dense | sparse), got 'tiny'"),
    # A number where a string belongs was ignored (the default taken, no trajectory written).
    ({"trajectory_file": 123}, "/sparseloop/trajectory_file must be a string, got 123"),
])
def test_node_rejects_bad_parameters(ros, params, message):
    import rospy
    if rospy.has_param("/sparseloop"):
        rospy.delete_param("/sparseloop")
    for k, v in params.items():
        rospy.set_param("/sparseloop/" + k, v)
    proc = ros.start([require("SPARSELOOP_NODE"), "__name:=sparseloop"], "bad_node")
    assert proc.wait(30) == 2
    log = pathlib.Path(proc.log_path).read_text()
    assert message in log, log[-2000:]
    rospy.delete_param("/sparseloop")


def test_help_and_bad_diagnostics_period():
    """`sparseloop_node --help` prints its usage and exits without a ROS master (it waited for one
    forever). The bad ~diagnostics_period is in test_node_rejects_bad_parameters."""
    r = subprocess.run([require("SPARSELOOP_NODE"), "--help"], capture_output=True, text=True,
                       timeout=30, env={k: v for k, v in os.environ.items()
                                        if k != "ROS_MASTER_URI"})
    assert r.returncode == 0, r.stderr
    assert "Usage: sparseloop_node" in r.stdout and "trajectory_file" in r.stdout, r.stdout


def test_launch_file_finds_the_node(ros):
    """roslaunch resolves the package folder of the build tree (ROS_PACKAGE_PATH) and its node."""
    package = pathlib.Path(require("SPARSELOOP_NODE")).parent.parent / "ros"
    env = dict(ros.env, ROS_PACKAGE_PATH=f"{package}:/usr/share")
    out = subprocess.run(["roslaunch", "--args", "/sparseloop", "sparseloop", "sparseloop.launch",
                          "image:=/kf/image", "pose:=/kf/pose"], env=env, check=True,
                         capture_output=True, text=True).stdout
    assert "sparseloop_node" in out and "image:=/kf/image" in out and "pose:=/kf/pose" in out, out


def cloud_msg(sequence, i, datatype):
    """The render's mapped pixels of frame i, back-projected with their depths (camera frame)."""
    import rospy
    from sensor_msgs.msg import PointCloud2, PointField
    px, depth = sequence.mapped(i)
    keep = depth > 0
    px, depth = px[keep].astype(np.float64), depth[keep].astype(np.float64)
    xyz = np.stack([(px[:, 0] - sequence.cx) / sequence.fx * depth,
                    (px[:, 1] - sequence.cy) / sequence.fy * depth, depth], axis=1)
    dtype, size = (np.float32, 4) if datatype == PointField.FLOAT32 else (np.float64, 8)
    m = PointCloud2()
    m.header.stamp = rospy.Time.from_sec(sequence.stamps[i])
    m.height, m.width = 1, len(xyz)
    m.fields = [PointField(n, k * size, datatype, 1) for k, n in enumerate("xyz")]
    m.is_bigendian, m.point_step, m.row_step, m.is_dense = False, 3 * size, 3 * size * len(xyz), True
    m.data = xyz.astype(dtype).tobytes()
    return m


def test_node_takes_odometry_compressed_images_and_mapped_points(ros, sequence):
    """pose_type odometry, image_transport compressed (the render's PNG files as they are), and
    the mapped pixels as float64 PointCloud2: the loops of `run` with its mapped/ pixels."""
    import rospy
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import CameraInfo, CompressedImage, PointCloud2, PointField
    run = NodeRun(ros, sequence.root, {"pose_type": "odometry", "image_transport": "compressed",
                                       "wait_for_points": True, "solve_while_running": False},
                  image_topic="/cam1/image", pose_topic="/vslam/odom", compressed=True)
    pubs = {"image": rospy.Publisher("/cam1/image/compressed", CompressedImage, queue_size=100),
            "info": rospy.Publisher(INFO, CameraInfo, queue_size=10, latch=True),
            "pose": rospy.Publisher("/vslam/odom", Odometry, queue_size=100),
            "points": rospy.Publisher("/mapped_points", PointCloud2, queue_size=100)}
    try:
        connect(run, pubs, sequence.info_msg())
        for i in range(60):
            p = sequence.pose_msg(i)
            odom = Odometry()
            odom.header, odom.pose.pose = p.header, p.pose
            img = CompressedImage()
            img.header.stamp, img.format = p.header.stamp, "png"
            img.data = sequence.images[i].read_bytes()
            pubs["image"].publish(img)
            pubs["pose"].publish(odom)
            pubs["points"].publish(cloud_msg(sequence, i, PointField.FLOAT64))
            time.sleep(0.02)
        wait_for(lambda: run.diag.get("keyframes", 0) >= 60, 60, "60 keyframes", run.proc)
        summary = run.finish()
    finally:
        unregister(pubs)
        run.close()
    assert summary["keyframes"] == 60 and summary["keyframes_without_pose"] == 0, summary
    assert summary["keyframes_with_points"] == 60, summary
    # The depths are used: every loop closes with a 3D-3D Sim(3), as in `run` with mapped pixels
    # (without them `run` has 8 of 32 two-view loops here).
    assert {m.data[14] for m in run.loops} == {3.0}
    # The projected points are the mapped pixels up to ~1e-12 px, and the extraction mask
    # truncates pixel coordinates, so a mask cell may shift by one pixel: the same loop queries
    # as `run`, each match within one keyframe of run's.
    node = dict(loop_pairs(run, sequence))
    ref = dict(sequence.run_mapped_loops)
    assert node.keys() == ref.keys()
    assert all(abs(node[q] - ref[q]) <= 1 for q in ref), (node, ref)


def test_node_takes_poses_from_tf(ros, sequence):
    """pose_type tf: each image's pose is the TF map <- cam0 at its stamp. Checked without loops
    (no loop check after keyframe 0), so the final path is the poses the node took: the raw poses.
    (With loops, tf2's interpolation at a stamp can differ from the stored transform in the last
    bit depending on which later transforms have arrived, and a near-tie loop match can move by
    one keyframe with it: run-to-run, not a wrong pose.)"""
    import rospy
    from geometry_msgs.msg import TransformStamped
    from sensor_msgs.msg import CameraInfo, Image
    from tf2_msgs.msg import TFMessage
    run = NodeRun(ros, sequence.root, {
        "config": {"use_mapped_pixels": False, "detector": {"check_every": 1000}},
        "pose_type": "tf", "world_frame": "map", "camera_frame": "cam0",
        "solve_while_running": False}, pose_topic=None)
    pubs = {"image": rospy.Publisher(IMAGE, Image, queue_size=100),
            "info": rospy.Publisher(INFO, CameraInfo, queue_size=10, latch=True),
            "tf": rospy.Publisher("/tf", TFMessage, queue_size=100)}
    try:
        connect(run, pubs, sequence.info_msg())
        # Stamps from 100 s: a TF lookup at ROS time 0 means "the latest", so frame 0's stamp 0
        # cannot name a transform (the node warns and takes no pose for such an image).
        for i in range(60):
            p = sequence.pose_msg(i, offset=100.0)
            t = TransformStamped()
            t.header.stamp, t.header.frame_id, t.child_frame_id = p.header.stamp, "map", "cam0"
            t.transform.translation.x = p.pose.position.x
            t.transform.translation.y = p.pose.position.y
            t.transform.translation.z = p.pose.position.z
            t.transform.rotation = p.pose.orientation
            pubs["tf"].publish(TFMessage([t]))
            pubs["image"].publish(sequence.image_msg(i, stamp=sequence.stamps[i] + 100.0))
            time.sleep(0.02)
        wait_for(lambda: run.diag.get("keyframes", 0) >= 59, 60, "59 keyframes", run.proc)
        summary = run.finish()
        wait_for(lambda: run.paths and len(run.paths[-1].poses) == 60, 10, "the final path")
    finally:
        unregister(pubs)
        run.close()
    assert summary["keyframes"] == 60 and summary["keyframes_without_pose"] == 0, summary
    assert not run.loops and not summary["loops"]
    path = run.paths[-1]
    assert path.header.frame_id == "map"
    for i, p in enumerate(path.poses):
        assert sequence.frame_of(p.header.stamp.to_sec() - 100.0) == i
        xyz = np.array([p.pose.position.x, p.pose.position.y, p.pose.position.z])
        q = np.array([p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z,
                      p.pose.orientation.w])
        assert np.abs(xyz - sequence.raw[i][:3, 3]).max() < 1e-9, i
        q_raw = quaternion_xyzw(sequence.raw[i][:3, :3])
        assert min(np.abs(q - q_raw).max(), np.abs(q + q_raw).max()) < 1e-9, i


def test_the_test_network_is_loopback_only(ros):
    """ctest runs this file through isolated.py: a network namespace whose only interface is
    loopback, so roscore, rosout and the node (whose XML-RPC servers bind every interface) listen
    on loopback only."""
    if os.environ.get("SPARSELOOP_NET_ISOLATED") != "1":
        pytest.skip("not run through tests/ros/isolated.py (no network namespace)")
    assert [name for _, name in socket.if_nameindex()] == ["lo"]
    listening = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as f:
            listening += [line.split()[1] for line in f.readlines()[1:] if line.split()[3] == "0A"]
    assert listening, "roscore listens"
