"""A ROS 2 detector and a ROS 2 planner around the project, over Zenoh, with independent code on
the ROS side (rosbags for the messages and their type hashes, eclipse-zenoh for the transport):

    ros_e2e.py hashes                  # rosbags' hashes of ros/msg/ against ROS 2 Jazzy's own
    ros_e2e.py run ENDPOINT            # against a fuser and two ROS-fed agents on ENDPOINT

`run` publishes vision_msgs/Detection3DArray on /veh/detections (rmw_zenoh's key, with its
attachment) and autoware_perception_msgs/DetectedObjects on /rsu/objects (the bridge's key),
three cars seen by both, the vehicle's in its own sensor frame; it subscribes to the fused
DetectedObjects on /v2x/objects and the TrackedObjects on /v2x/tracks under the rmw_zenoh keys
rosbags' type hashes name, and checks each fused message (three cars where they are in the
map, in frame "map") and the tracks (three, each keeping its id).
"""

import glob
import math
import os
import sys
import time

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

HERE = os.path.dirname(os.path.abspath(__file__))
MSGS = os.path.join(HERE, "..", "msg")
OURS = ("vision_msgs", "autoware_perception_msgs")


def definitions():
    """Every ros/msg file: full name -> text."""
    out = {}
    for path in sorted(glob.glob(os.path.join(MSGS, "*.msg"))):
        pkg, name, _ = os.path.basename(path).split(".")
        out[f"{pkg}/msg/{name}"] = open(path).read()
    return out


def typestore():
    """ROS 2 Jazzy's types with the project's vision_msgs and autoware_perception_msgs."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    add = {}
    for name, text in definitions().items():
        if name.split("/")[0] in OURS:
            add.update(get_types_from_msg(text, name))
    ts.register(add)
    return ts


def fail(what):
    sys.exit(f"FAIL: {what}")


def hashes():
    """The common types of ros/msg hash as Jazzy's own definitions do."""
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    mine = get_typestore(Stores.EMPTY)
    add = {}
    for name, text in definitions().items():
        add.update(get_types_from_msg(text, name))
    mine.register(add)
    n = 0
    for name in definitions():
        if name.split("/")[0] in OURS:
            continue
        if mine.hash_rihs01(name) != jazzy.hash_rihs01(name):
            fail(f"{name}: ros/msg hashes {mine.hash_rihs01(name)}, Jazzy {jazzy.hash_rihs01(name)}")
        n += 1
    print(f"{n} common message types of ros/msg hash as ROS 2 Jazzy's")


def dds(name):
    pkg, kind, n = name.split("/")
    return f"{pkg}::{kind}::dds_::{n}_"


def run(endpoint):
    import zenoh

    ts = typestore()
    T = ts.types
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    Pose, Point, Quat = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    Vector3, PoseCov = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/PoseWithCovariance"]
    Twist, TwistCov = T["geometry_msgs/msg/Twist"], T["geometry_msgs/msg/TwistWithCovariance"]
    Polygon = T["geometry_msgs/msg/Polygon"]
    Hyp, HypPose = T["vision_msgs/msg/ObjectHypothesis"], T["vision_msgs/msg/ObjectHypothesisWithPose"]
    BBox, Det, DetArray = T["vision_msgs/msg/BoundingBox3D"], T["vision_msgs/msg/Detection3D"], T["vision_msgs/msg/Detection3DArray"]
    Cls, Kin = T["autoware_perception_msgs/msg/ObjectClassification"], T["autoware_perception_msgs/msg/DetectedObjectKinematics"]
    Shape, Obj = T["autoware_perception_msgs/msg/Shape"], T["autoware_perception_msgs/msg/DetectedObject"]
    Objs = T["autoware_perception_msgs/msg/DetectedObjects"]
    import numpy as np

    cars = [(20.0, 10.0), (35.0, 14.0), (50.0, 8.0)]  # in the map
    # The vehicle's sensor frame: at (100, 50) in the map, heading +y (90 degrees): map (x, y)
    # is sensor (y - 50, 100 - x).
    def in_sensor(x, y):
        return y - 50.0, 100.0 - x

    def quat(yaw):
        return Quat(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def cov(std):
        c = np.zeros(36)
        for i, s in enumerate([std, std, std, 0.0, 0.0, 0.05]):
            c[i * 7] = s * s
        return c

    def header(t_ns, frame):
        return Header(stamp=Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id=frame)

    def veh_msg(t_ns):
        dets = []
        for i, (x, y) in enumerate(cars):
            sx, sy = in_sensor(x + 0.2, y)
            dets.append(Det(
                header=header(t_ns, "lidar"),
                results=[HypPose(hypothesis=Hyp(class_id="car", score=0.9),
                                 pose=PoseCov(pose=Pose(position=Point(x=sx, y=sy, z=0.8), orientation=quat(-math.pi / 2)), covariance=cov(0.3)))],
                bbox=BBox(center=Pose(position=Point(x=sx, y=sy, z=0.8), orientation=quat(-math.pi / 2)), size=Vector3(x=4.5, y=1.9, z=1.6)),
                id=str(i + 1)))
        return DetArray(header=header(t_ns, "lidar"), detections=dets)

    def rsu_msg(t_ns):
        objs = []
        for x, y in cars:
            objs.append(Obj(
                existence_probability=0.8,
                classification=[Cls(label=1, probability=0.9)],
                kinematics=Kin(pose_with_covariance=PoseCov(pose=Pose(position=Point(x=x - 0.2, y=y, z=0.8), orientation=quat(0.0)), covariance=cov(0.3)),
                               has_position_covariance=True, orientation_availability=2,
                               twist_with_covariance=TwistCov(twist=Twist(linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)), covariance=np.zeros(36)),
                               has_twist=False, has_twist_covariance=False),
                shape=Shape(type=0, footprint=Polygon(points=[]), dimensions=Vector3(x=4.5, y=1.9, z=1.6))))
        return Objs(header=header(t_ns, "map"), objects=objs)

    det_name = "vision_msgs/msg/Detection3DArray"
    objs_name = "autoware_perception_msgs/msg/DetectedObjects"
    veh_key = f"0/veh/detections/{dds(det_name)}/{ts.hash_rihs01(det_name)}"
    rsu_key = "rsu/objects"
    out_key = f"0/v2x/objects/{dds(objs_name)}/{ts.hash_rihs01(objs_name)}"
    tracks_name = "autoware_perception_msgs/msg/TrackedObjects"
    tracks_key = f"0/v2x/tracks/{dds(tracks_name)}/{ts.hash_rihs01(tracks_name)}"

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", f'["{endpoint}"]')
    conf.insert_json5("scouting/multicast/enabled", "false")
    got, tracked = [], []
    with zenoh.open(conf) as s:
        sub = s.declare_subscriber(out_key, lambda sample: got.append(bytes(sample.payload.to_bytes())))
        tsub = s.declare_subscriber(tracks_key, lambda sample: tracked.append(bytes(sample.payload.to_bytes())))
        veh = s.declare_publisher(veh_key)
        rsu = s.declare_publisher(rsu_key)
        deadline = time.time() + 20
        while not (veh.matching_status.matching and rsu.matching_status.matching):
            if time.time() > deadline:
                fail("the agents did not subscribe to the ROS topics within 20 s")
            time.sleep(0.05)
        time.sleep(1.0)  # the fuser hears both agents' liveliness
        sent = 20
        for k in range(sent):
            t_ns = time.time_ns()
            attachment = (k + 1).to_bytes(8, "little", signed=True) + t_ns.to_bytes(8, "little", signed=True) + bytes([16]) + bytes(16)
            veh.put(bytes(ts.serialize_cdr(veh_msg(t_ns), det_name)), attachment=attachment)
            rsu.put(bytes(ts.serialize_cdr(rsu_msg(t_ns), objs_name)))
            time.sleep(0.1)
        deadline = time.time() + 5
        while len(got) < sent // 2 and time.time() < deadline:
            time.sleep(0.05)
        sub.undeclare()
        tsub.undeclare()
    if len(got) < sent // 2:
        fail(f"{len(got)} fused DetectedObjects on {out_key} for {sent} messages sent")
    fused_both = 0
    for raw in got:
        m = ts.deserialize_cdr(raw, objs_name)
        if m.header.frame_id != "map":
            fail(f"frame {m.header.frame_id}")
        pos = sorted((o.kinematics.pose_with_covariance.pose.position.x, o.kinematics.pose_with_covariance.pose.position.y) for o in m.objects)
        if len(pos) != 3:
            continue  # a window one agent missed
        fused_both += 1
        for (x, y), (gx, gy) in zip(pos, cars):
            if math.hypot(x - gx, y - gy) > 0.25:
                fail(f"a fused car at ({x:.2f}, {y:.2f}) for ({gx}, {gy})")
        for o in m.objects:
            if o.classification[0].label != 1 or not o.kinematics.has_position_covariance:
                fail("a fused car is not a car with its covariance")
    if fused_both < sent // 2:
        fail(f"{fused_both} of {len(got)} fused messages hold the three cars")
    ids = {}
    for raw in tracked:
        m = ts.deserialize_cdr(raw, tracks_name)
        for o in m.objects:
            p = o.kinematics.pose_with_covariance.pose.position
            car = min(range(3), key=lambda i: math.hypot(p.x - cars[i][0], p.y - cars[i][1]))
            ids.setdefault(car, set()).add(bytes(o.object_id.uuid))
    if sorted(ids) != [0, 1, 2] or any(len(v) != 1 for v in ids.values()) or len(set().union(*ids.values())) != 3:
        fail(f"tracks: {len(tracked)} messages, ids by car {ids}")
    print(f"{len(got)} fused DetectedObjects for {sent} sent by each detector: {fused_both} with the three cars where they are; "
          f"{len(tracked)} TrackedObjects, each car one track id throughout")


if __name__ == "__main__":
    if sys.argv[1:2] == ["hashes"]:
        hashes()
    elif sys.argv[1:2] == ["run"]:
        run(sys.argv[2])
    else:
        sys.exit(__doc__)
