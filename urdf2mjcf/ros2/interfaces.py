"""The ROS 2 interfaces the server speaks, as their ``.msg`` / ``.srv`` files define them.

Fields only, in order, with every type fully qualified (``pkg/Name``): constants and
default values are left out, as they are of the type hash (REP-2016) and of CDR. The
texts are those of ROS 2 Jazzy (Humble's and Kilted's are the same for these types);
``mujoco_ros2_control_msgs`` as ros-controls/mujoco_ros2_control defines them.
"""

from __future__ import annotations

import re

MESSAGES: dict[str, str] = {
    "builtin_interfaces/msg/Time": "int32 sec\nuint32 nanosec",
    "builtin_interfaces/msg/Duration": "int32 sec\nuint32 nanosec",
    "std_msgs/msg/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "std_msgs/msg/String": "string data",
    "std_msgs/msg/Bool": "bool data",
    "std_msgs/msg/MultiArrayDimension": "string label\nuint32 size\nuint32 stride",
    "std_msgs/msg/MultiArrayLayout": "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset",
    "std_msgs/msg/Float64MultiArray": "std_msgs/MultiArrayLayout layout\nfloat64[] data",
    "rosgraph_msgs/msg/Clock": "builtin_interfaces/Time clock",
    "geometry_msgs/msg/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/msg/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/msg/Quaternion": "float64 x\nfloat64 y\nfloat64 z\nfloat64 w",
    "geometry_msgs/msg/Pose": "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation",
    "geometry_msgs/msg/PoseStamped": "std_msgs/Header header\ngeometry_msgs/Pose pose",
    "geometry_msgs/msg/PoseWithCovariance": "geometry_msgs/Pose pose\nfloat64[36] covariance",
    "geometry_msgs/msg/Twist": "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular",
    "geometry_msgs/msg/TwistStamped": "std_msgs/Header header\ngeometry_msgs/Twist twist",
    "geometry_msgs/msg/TwistWithCovariance": "geometry_msgs/Twist twist\nfloat64[36] covariance",
    "geometry_msgs/msg/Transform": (
        "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation"
    ),
    "geometry_msgs/msg/TransformStamped": (
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform"
    ),
    "geometry_msgs/msg/Wrench": "geometry_msgs/Vector3 force\ngeometry_msgs/Vector3 torque",
    "geometry_msgs/msg/WrenchStamped": "std_msgs/Header header\ngeometry_msgs/Wrench wrench",
    "tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms",
    "sensor_msgs/msg/JointState": (
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n"
        "float64[] effort"
    ),
    "sensor_msgs/msg/Image": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
        "uint8 is_bigendian\nuint32 step\nuint8[] data"
    ),
    "sensor_msgs/msg/RegionOfInterest": (
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify"
    ),
    "sensor_msgs/msg/CameraInfo": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
        "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n"
        "uint32 binning_y\nsensor_msgs/RegionOfInterest roi"
    ),
    "sensor_msgs/msg/LaserScan": (
        "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n"
        "float32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\n"
        "float32[] ranges\nfloat32[] intensities"
    ),
    "sensor_msgs/msg/Imu": (
        "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n"
        "float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n"
        "float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n"
        "float64[9] linear_acceleration_covariance"
    ),
    "trajectory_msgs/msg/JointTrajectoryPoint": (
        "float64[] positions\nfloat64[] velocities\nfloat64[] accelerations\n"
        "float64[] effort\nbuiltin_interfaces/Duration time_from_start"
    ),
    "trajectory_msgs/msg/JointTrajectory": (
        "std_msgs/Header header\nstring[] joint_names\n"
        "trajectory_msgs/JointTrajectoryPoint[] points"
    ),
    "nav_msgs/msg/Odometry": (
        "std_msgs/Header header\nstring child_frame_id\n"
        "geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist"
    ),
    # what FollowJointTrajectory's goal and feedback carry beside a JointTrajectory
    "trajectory_msgs/msg/MultiDOFJointTrajectoryPoint": (
        "geometry_msgs/Transform[] transforms\ngeometry_msgs/Twist[] velocities\n"
        "geometry_msgs/Twist[] accelerations\nbuiltin_interfaces/Duration time_from_start"
    ),
    "trajectory_msgs/msg/MultiDOFJointTrajectory": (
        "std_msgs/Header header\nstring[] joint_names\n"
        "trajectory_msgs/MultiDOFJointTrajectoryPoint[] points"
    ),
    # an action's goal ids and its status topic (rmw_zenoh's <action>/_action/status)
    "unique_identifier_msgs/msg/UUID": "uint8[16] uuid",
    "action_msgs/msg/GoalInfo": (
        "unique_identifier_msgs/UUID goal_id\nbuiltin_interfaces/Time stamp"
    ),
    "action_msgs/msg/GoalStatus": "action_msgs/GoalInfo goal_info\nint8 status",
    "action_msgs/msg/GoalStatusArray": "action_msgs/GoalStatus[] status_list",
    # what every service's Event message carries (rosidl adds it to each service)
    "service_msgs/msg/ServiceEventInfo": (
        "uint8 event_type\nbuiltin_interfaces/Time stamp\nchar[16] client_gid\n"
        "int64 sequence_number"
    ),
    # FollowJointTrajectory's tolerances (ros-controls/control_msgs)
    "control_msgs/msg/JointTolerance": (
        "string name\nfloat64 position\nfloat64 velocity\nfloat64 acceleration"
    ),
    "control_msgs/msg/JointComponentTolerance": (
        "string joint_name\nuint16 component\nfloat64 position\nfloat64 velocity\n"
        "float64 acceleration"
    ),
    "mujoco_ros2_control_msgs/msg/FreeJointState": (
        "string name\ngeometry_msgs/PoseStamped pose\ngeometry_msgs/TwistStamped twist"
    ),
    "mujoco_ros2_control_msgs/msg/SimulationState": (
        "sensor_msgs/JointState joint_states\nmujoco_ros2_control_msgs/FreeJointState[] free_joints"
    ),
}
"""``pkg/msg/Name`` -> its fields, one ``type name`` a line."""

SERVICES: dict[str, tuple[str, str]] = {
    "mujoco_ros2_control_msgs/srv/SetPause": ("bool paused", "bool success\nstring message"),
    "mujoco_ros2_control_msgs/srv/StepSimulation": (
        "uint32 steps",
        "bool success\nstring message",
    ),
    "mujoco_ros2_control_msgs/srv/ResetWorld": (
        "string keyframe\nmujoco_ros2_control_msgs/SimulationState state_overrides",
        "bool success\nstring message",
    ),
}
"""``pkg/srv/Name`` -> (request fields, response fields)."""

ACTIONS: dict[str, tuple[str, str, str]] = {
    "control_msgs/action/FollowJointTrajectory": (
        "trajectory_msgs/JointTrajectory trajectory\n"
        "trajectory_msgs/MultiDOFJointTrajectory multi_dof_trajectory\n"
        "control_msgs/JointTolerance[] path_tolerance\n"
        "control_msgs/JointComponentTolerance[] component_path_tolerance\n"
        "control_msgs/JointTolerance[] goal_tolerance\n"
        "control_msgs/JointComponentTolerance[] component_goal_tolerance\n"
        "builtin_interfaces/Duration goal_time_tolerance",
        "int32 error_code\nstring error_string",
        "std_msgs/Header header\nstring[] joint_names\n"
        "trajectory_msgs/JointTrajectoryPoint desired\n"
        "trajectory_msgs/JointTrajectoryPoint actual\n"
        "trajectory_msgs/JointTrajectoryPoint error\n"
        "string[] multi_dof_joint_names\n"
        "trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_desired\n"
        "trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_actual\n"
        "trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_error",
    ),
}
"""``pkg/action/Name`` -> (goal, result, feedback fields)."""

SERVICES["action_msgs/srv/CancelGoal"] = (
    "action_msgs/GoalInfo goal_info",
    "int8 return_code\naction_msgs/GoalInfo[] goals_canceling",
)


def action_parts(
    action: str, goal: str, result: str, feedback: str
) -> tuple[dict[str, str], dict[str, tuple[str, str]]]:
    """What rosidl makes of an action (``pkg/action/Name``): its ``_Goal``, ``_Result``,
    ``_Feedback`` and ``_FeedbackMessage`` messages and its ``_SendGoal`` and
    ``_GetResult`` services, all in ``pkg/action/``."""
    messages = {
        f"{action}_Goal": goal,
        f"{action}_Result": result,
        f"{action}_Feedback": feedback,
        f"{action}_FeedbackMessage": (
            f"unique_identifier_msgs/UUID goal_id\n{action}_Feedback feedback"
        ),
    }
    services = {
        f"{action}_SendGoal": (
            f"unique_identifier_msgs/UUID goal_id\n{action}_Goal goal",
            "bool accepted\nbuiltin_interfaces/Time stamp",
        ),
        f"{action}_GetResult": (
            "unique_identifier_msgs/UUID goal_id",
            f"int8 status\n{action}_Result result",
        ),
    }
    return messages, services


for _action, _texts in ACTIONS.items():
    _messages, _services = action_parts(_action, *_texts)
    MESSAGES.update(_messages)
    SERVICES.update(_services)

_ARRAY = re.compile(r"\[[^\]]*\]$")


def full_name(kind: str, package: str) -> str:
    """``pkg/Name`` (or a bare ``Name`` of ``package``) -> ``pkg/msg/Name``; a name
    already full (``pkg/action/Name_Goal``) as it is."""
    if kind.count("/") == 2:
        return kind
    pkg, _, name = kind.rpartition("/")
    return f"{pkg or package}/msg/{name}"


def fields(definition: str) -> list[tuple[str, str]]:
    """(type, name) of each field of a definition's text."""
    out = []
    for raw in definition.splitlines():
        line = raw.split("#", 1)[0].strip()
        if line:
            kind, name = line.split()[:2]
            out.append((kind, name))
    return out


def nested(kind: str) -> str | None:
    """The message type a field type names (``pkg/Name`` of ``geometry_msgs/Point[]``),
    None for a primitive or a string."""
    base = _ARRAY.sub("", kind)
    return base if "/" in base or base[:1].isupper() else None


def service_parts(service: str) -> dict[str, str]:
    """A service's request and response messages as rosidl makes them:
    ``pkg/srv/Name_Request`` and ``pkg/srv/Name_Response`` -> their fields."""
    request, response = SERVICES[service]
    return {f"{service}_Request": request, f"{service}_Response": response}


def definition_text(datatype: str) -> str:
    """``datatype`` and every type it uses, as ``ros2 bag`` stores a definition (each used
    type after a line of 80 '=' and ``MSG: pkg/Name``): what :mod:`..runner.cdr` reads.
    A service's ``_Request`` / ``_Response`` is given by its full name."""
    service = datatype.rsplit("_", 1)[0]
    parts = service_parts(service) if service in SERVICES else {}
    text = parts.get(datatype) or MESSAGES[datatype]
    package = datatype.split("/")[0]
    order: list[str] = []

    def visit(body: str, pkg: str) -> None:
        for kind, _ in fields(body):
            sub = nested(kind)
            if sub is None:
                continue
            full = full_name(sub, pkg)
            if full not in order:
                order.append(full)
                visit(MESSAGES[full], full.split("/")[0])

    visit(text, package)
    out = [_qualified(text, package)]
    for full in order:
        pkg, _, name = full.split("/")
        out.append(f"{'=' * 80}\nMSG: {pkg}/{name}\n{_qualified(MESSAGES[full], pkg)}")
    return "\n".join(out) + "\n"


def _qualified(body: str, package: str) -> str:
    lines = []
    for kind, name in fields(body):
        sub = nested(kind)
        if sub is not None and "/" not in sub:
            kind = f"{package}/{kind}"
        elif sub is not None and sub.count("/") == 2:  # pkg/action/X as the reader names it
            pkg, _, rest = kind.split("/", 2)
            kind = f"{pkg}/{rest}"
        lines.append(f"{kind} {name}")
    return "\n".join(lines)
