"""Sensors on the topics their description names: Gazebo's tags read as ROS reads them
(a ROS 2 gazebo_ros plugin's namespace and ``~/out`` remapping, a ROS 1 plugin's
``robotNamespace``/``topicName``, gz's ``<topic>``), kept by the conversion in the MJCF
as ``<custom>`` texts, and used by the ROS 2 server's IMU and LaserScan publishers with
the frames named; a description that names none keeps the names made from sites."""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest
from lxml import etree

from urdf2mjcf import api
from urdf2mjcf.passes.sensors.gazebo import ros_camera_topic, ros_frame, ros_topic
from urdf2mjcf.ros2 import described
from urdf2mjcf.ros2.scans import Scans
from urdf2mjcf.ros2.sensors import Sensors

ROOT = Path(__file__).resolve().parents[2]
SIM_ARM = ROOT / "tests" / "data" / "sim_robot" / "urdf" / "sim_arm.urdf.xacro"


@pytest.mark.parametrize(
    ("xml", "topic", "frame"),
    [
        (  # ROS 2 gazebo_ros: <ros> namespace, ~/out remapped
            '<sensor type="imu"><plugin name="p" filename="libgazebo_ros_imu_sensor.so">'
            "<ros><namespace>/demo</namespace><remapping>~/out:=imu/data</remapping></ros>"
            "<frame_name>imu_link</frame_name></plugin></sensor>",
            "/demo/imu/data",
            "imu_link",
        ),
        (  # ROS 2 without a remapping: ~/out under the plugin's name
            '<sensor type="imu"><plugin name="bno" filename="libgazebo_ros_imu_sensor.so">'
            "<ros><namespace>arm</namespace></ros></plugin></sensor>",
            "/arm/bno/out",
            None,
        ),
        (  # an absolute remapping leaves the namespace
            '<sensor type="ray"><plugin name="p" filename="libgazebo_ros_ray_sensor.so">'
            "<ros><namespace>/x</namespace><remapping>~/out:=/scan</remapping></ros>"
            "</plugin></sensor>",
            "/scan",
            None,
        ),
        (  # ROS 1
            '<sensor type="ray"><plugin name="l" filename="libgazebo_ros_laser.so">'
            "<robotNamespace>r</robotNamespace><topicName>front/scan</topicName>"
            "<frameName>laser_link</frameName></plugin></sensor>",
            "/r/front/scan",
            "laser_link",
        ),
        (  # gz sim
            '<sensor type="imu"><topic>imu</topic><gz_frame_id>base_imu</gz_frame_id></sensor>',
            "/imu",
            "base_imu",
        ),
        ('<sensor type="imu"><always_on>1</always_on></sensor>', None, None),
        ('<sensor type="imu"><topic>not a name!</topic></sensor>', None, None),
    ],
    ids=["ros2", "ros2-default", "ros2-absolute", "ros1", "gz", "none", "not-a-name"],
)
def test_the_topic_and_frame_as_ros_reads_the_tags(xml, topic, frame):
    sensor = etree.fromstring(xml)
    assert ros_topic(sensor) == topic
    assert ros_frame(sensor) == frame


@pytest.mark.parametrize(
    ("xml", "topic"),
    [
        (  # ROS 1, as TALOS's and TIAGo's descriptions write it
            '<sensor type="depth" name="rgbd"><plugin filename="libgazebo_ros_openni_kinect.so">'
            "<cameraName>rgbd</cameraName><imageTopicName>rgb/image_raw</imageTopicName>"
            "</plugin></sensor>",
            "/rgbd/rgb/image_raw",
        ),
        (  # ROS 2 gazebo_ros_camera: namespace, camera_name, ~/image_raw
            '<sensor type="camera" name="front"><plugin filename="libgazebo_ros_camera.so">'
            "<ros><namespace>/r</namespace></ros><camera_name>mast</camera_name></plugin></sensor>",
            "/r/mast/image_raw",
        ),
        (  # no <ros>, only a frame: nothing named (sim_arm's camera)
            '<sensor type="depth" name="mast_camera"><plugin filename="libgazebo_ros_camera.so">'
            "<frame_name>camera_optical_frame</frame_name></plugin></sensor>",
            None,
        ),
    ],
    ids=["ros1", "ros2", "frame-only"],
)
def test_a_cameras_image_topic_as_ros_reads_the_tags(xml, topic):
    assert ros_camera_topic(etree.fromstring(xml)) == topic
    if topic:
        assert described.camera_info_topic(topic) == topic.rsplit("/", 1)[0] + "/camera_info"


def test_talos_cameras_keep_their_topics(tmp_path):
    """example-robot-data's TALOS names its head camera's ir and rgb image topics with a
    ROS 1 openni plugin: both cameras are served there, in the optical frame it names."""
    from tests.corpus import example_robot_data_share
    from urdf2mjcf.ros2.cameras import Cameras

    share = example_robot_data_share()
    out = tmp_path / "talos" / "robot.xml"
    api.convert(
        share / "example-robot-data/robots/talos_data/robots/talos_reduced.urdf",
        out,
        package_paths=[share],
        use_environment=False,
        scene=False,
        cache_dir=tmp_path / "cache",
    )
    m = mujoco.MjModel.from_xml_path(str(out))
    topics = Cameras(m, 10.0).topics
    assert topics["rgbd_optical_frame"] == ("/rgbd/ir/image_raw", "rgbd_optical_frame")
    assert topics["rgbd_optical_frame_2"] == ("/rgbd/rgb/image_raw", "rgbd_optical_frame")


def _convert(tmp_path: Path, *args: str) -> mujoco.MjModel:
    out = tmp_path / "robot.xml"
    api.convert(
        SIM_ARM,
        out,
        package_paths=[SIM_ARM.parents[2]],
        use_environment=False,
        args=dict(a.split(":=") for a in ("lidar_samples:=3", *args)),
        cache_dir=tmp_path / "cache",
        scene=False,
    )
    return mujoco.MjModel.from_xml_path(str(out))


def test_the_server_publishes_on_the_described_topics(tmp_path):
    m = _convert(tmp_path, "ros_topics:=true")
    assert described.topics(m) == {
        ("imu", "imu_link"): ("/demo/imu/data", "imu_link"),
        ("scan", "laser_link"): ("/sim_arm/front/scan", "laser_link"),
    }
    sensors, scans = Sensors(m), Scans(m)
    assert sensors.topics["imu:imu_link"] == "/demo/imu/data"
    assert sensors.topics["wrench:ft_frame"] == "/ft_frame/wrench"  # ros2_control: none named
    assert scans.named == {"laser_link": ("/sim_arm/front/scan", "laser_link")}


def test_a_description_naming_no_topic_keeps_the_made_names(tmp_path):
    m = _convert(tmp_path)
    assert m.ntext == 0 and described.topics(m) == {}
    assert Sensors(m).topics["imu:imu_link"] == "/imu_link/imu"
    assert Scans(m).named == {"laser_link": ("/laser_link/scan", None)}
