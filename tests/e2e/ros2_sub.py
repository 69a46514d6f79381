"""ros2_sub.py - a ROS 2 topic subscriber written with the PyPI `cyclonedds` binding and its own copy of the ROS 2
message types (not rbx1's IDL): prints every sample of rt/<ns>/<topic> as a JSON line with its receive time.
Run with the venv's python (tools/install-deps makes it): ros2_sub.py DOMAIN NS TOPIC [TOPIC...] --seconds S."""
import argparse
import json
import sys
import time
from dataclasses import asdict, dataclass

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.annotations import final
from cyclonedds.idl.types import array, float64, int32, sequence, uint32
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


# ROS 2 Humble/Jazzy message definitions in ROS 2's DDS naming (package::msg::dds_::Name_).
@final
@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@final
@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@final
@dataclass
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str


@final
@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header
    name: sequence[str]
    position: sequence[float64]
    velocity: sequence[float64]
    effort: sequence[float64]


@final
@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@final
@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@final
@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@final
@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header
    pose: Pose


@final
@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose
    covariance: array[float64, 36]


@final
@dataclass
class Point2D(IdlStruct, typename="vision_msgs::msg::dds_::Point2D_"):
    x: float64
    y: float64


@final
@dataclass
class Pose2D(IdlStruct, typename="vision_msgs::msg::dds_::Pose2D_"):
    position: Point2D
    theta: float64


@final
@dataclass
class BoundingBox2D(IdlStruct, typename="vision_msgs::msg::dds_::BoundingBox2D_"):
    center: Pose2D
    size_x: float64
    size_y: float64


@final
@dataclass
class ObjectHypothesis(IdlStruct, typename="vision_msgs::msg::dds_::ObjectHypothesis_"):
    class_id: str
    score: float64


@final
@dataclass
class ObjectHypothesisWithPose(IdlStruct, typename="vision_msgs::msg::dds_::ObjectHypothesisWithPose_"):
    hypothesis: ObjectHypothesis
    pose: PoseWithCovariance


@final
@dataclass
class Detection2D(IdlStruct, typename="vision_msgs::msg::dds_::Detection2D_"):
    header: Header
    results: sequence[ObjectHypothesisWithPose]
    bbox: BoundingBox2D
    id: str


@final
@dataclass
class Detection2DArray(IdlStruct, typename="vision_msgs::msg::dds_::Detection2DArray_"):
    header: Header
    detections: sequence[Detection2D]


TOPICS = {
    "joint_states": (JointState, False),
    "robot_description": (String, True),  # transient local: a late reader gets the last sample
    "detections": (Detection2DArray, False),
    "tool_pose": (PoseStamped, False),
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("domain", type=int)
    ap.add_argument("ns")
    ap.add_argument("topics", nargs="+", choices=sorted(TOPICS))
    ap.add_argument("--seconds", type=float, default=10)
    ap.add_argument("--count", type=int, default=0, help="stop after this many samples of the first topic")
    args = ap.parse_args()
    dp = DomainParticipant(args.domain)
    readers = []
    for name in args.topics:
        cls, latched = TOPICS[name]
        qos = Qos(Policy.Reliability.Reliable(duration(seconds=1)),
                  Policy.History.KeepLast(1 if latched else 10),
                  Policy.Durability.TransientLocal if latched else Policy.Durability.Volatile)
        readers.append((name, DataReader(dp, Topic(dp, f"rt/{args.ns}/{name}", cls), qos=qos)))
    print(json.dumps({"ready": True}), flush=True)
    deadline = time.monotonic() + args.seconds
    first = 0
    while time.monotonic() < deadline:
        got = False
        for name, reader in readers:
            for sample in reader.take(N=100):
                got = True
                print(json.dumps({"topic": name, "t_recv": time.time(), "sample": asdict(sample)}), flush=True)
                if name == args.topics[0]:
                    first += 1
        if args.count and first >= args.count:
            break
        if not got:
            time.sleep(0.005)


if __name__ == "__main__":
    sys.exit(main())
