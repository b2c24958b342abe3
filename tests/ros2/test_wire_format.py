"""rmw_zenoh's wire format against the strings its design document and REP-2016 give,
and every type hash we use against rosbags' own implementation of REP-2016."""

from __future__ import annotations

import struct

import pytest

from urdf2mjcf.ros2 import attachment, interfaces, keyexpr, liveliness, type_hash
from urdf2mjcf.runner import cdr

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
ADD_TWO_INTS_HASH = "RIHS01_e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a"


@pytest.fixture
def add_two_ints(monkeypatch):
    # example_interfaces/srv/AddTwoInts, the design document's service
    monkeypatch.setitem(
        interfaces.SERVICES, "example_interfaces/srv/AddTwoInts", ("int64 a\nint64 b", "int64 sum")
    )
    return "example_interfaces/srv/AddTwoInts"


def test_the_design_documents_key_expressions(add_two_ints):
    assert keyexpr.data_keyexpr(0, "/chatter", "std_msgs/msg/String") == (
        f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    )
    assert keyexpr.data_keyexpr(0, "/robot1/chatter", "std_msgs/msg/String") == (
        f"0/robot1/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    )
    assert keyexpr.data_keyexpr(2, "/add_two_ints", add_two_ints) == (
        f"2/add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/{ADD_TWO_INTS_HASH}"
    )


def test_the_design_documents_liveliness_tokens(add_two_ints):
    listener = liveliness.Node(2, "aac3178e146ba6f1fc6e6a4085e77f21", "listener")
    assert listener.token() == "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
    assert listener.endpoint(10, "MS", "/chatter", "std_msgs/msg/String", keyexpr.QoS()) == (
        "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/"
        f"std_msgs::msg::dds_::String_/{STRING_HASH}/::,10:,:,:,,"
    )
    talker = liveliness.Node(2, "8b20917502ee955ac4476e0266340d5c", "talker")
    assert talker.endpoint(10, "MP", "/chatter", "std_msgs/msg/String", keyexpr.QoS(7)) == (
        "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
        f"std_msgs::msg::dds_::String_/{STRING_HASH}/::,7:,:,:,,"
    )
    server = liveliness.Node(2, "f9980ee0495eaafb3e38f0d19e2eae12", "add_two_ints_server")
    assert server.endpoint(10, "SS", "/add_two_ints", add_two_ints, keyexpr.QoS()) == (
        "@ros2_lv/2/f9980ee0495eaafb3e38f0d19e2eae12/0/10/SS/%/%/add_two_ints_server/"
        f"%add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/{ADD_TWO_INTS_HASH}"
        "/::,10:,:,:,,"
    )


def test_qos_is_written_only_where_it_differs_from_rmw_zenohs_default():
    assert keyexpr.QoS(depth=42).keyexpr() == "::,:,:,:,,"
    # /tf_static: transient local (1), depth 1; /clock: best effort (2), depth 1
    assert keyexpr.LATCHED.keyexpr() == ":1:,1:,:,:,,"
    assert keyexpr.CLOCK.keyexpr() == "2::,1:,:,:,,"


def test_a_namespaced_node_and_its_token_read_back():
    node = liveliness.Node(0, "ab12", "sim", namespace="/rover1")
    token = node.endpoint(3, "MP", "/rover1/odom", "nav_msgs/msg/Odometry", keyexpr.QoS())
    assert token.startswith("@ros2_lv/0/ab12/0/3/MP/%/%rover1/sim/%rover1%odom/")
    e = liveliness.parse(token)
    assert (e.namespace, e.node_name, e.topic, e.kind) == ("/rover1", "sim", "/rover1/odom", "MP")
    assert e.type_hash == type_hash.type_hash("nav_msgs/msg/Odometry")
    with pytest.raises(ValueError):
        liveliness.parse("@ros2_lv/0/ab12/0/3/XX/%/%/sim")


def test_names_that_are_not_fully_qualified_are_refused():
    for bad in ("chatter", "/a//b", "/a/", "/a b"):
        with pytest.raises(ValueError):
            keyexpr.data_keyexpr(0, bad, "std_msgs/msg/String")


def test_the_attachment_is_33_little_endian_bytes():
    gid = bytes(range(16))
    data = attachment.Attachment(7, 1_700_000_000_123_456_789, gid).encode()
    assert len(data) == 33
    assert data[:8] == struct.pack("<q", 7)
    assert data[8:16] == struct.pack("<q", 1_700_000_000_123_456_789)
    assert data[16] == 16 and data[17:] == gid
    assert attachment.decode(data) == attachment.Attachment(7, 1_700_000_000_123_456_789, gid)
    with pytest.raises(ValueError):
        attachment.decode(data[:-1])
    with pytest.raises(ValueError):
        attachment.decode(data[:16] + b"\x0f" + gid)


def test_the_design_documents_type_hashes_are_computed(add_two_ints):
    assert type_hash.type_hash("std_msgs/msg/String") == STRING_HASH
    assert type_hash.type_hash(add_two_ints) == ADD_TWO_INTS_HASH


def _rosbags_store():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    extra = {}
    for name, text in interfaces.MESSAGES.items():
        if name.startswith(("mujoco_ros2_control_msgs/", "control_msgs/")):
            extra.update(get_types_from_msg(text, name))
    store.register(extra)
    return store


# rosbags reads a .msg file's char as IDL char (type id 13); rosidl makes it uint8 (3),
# which the design document's AddTwoInts hash (its event message holds a
# ServiceEventInfo with char[16] client_gid) confirms above.
ROSBAGS_CHAR = {"service_msgs/msg/ServiceEventInfo"}


@pytest.mark.parametrize("name", sorted(set(interfaces.MESSAGES) - ROSBAGS_CHAR))
def test_every_message_types_hash_agrees_with_rosbags(name):
    assert type_hash.type_hash(name) == _rosbags_store().hash_rihs01(name)


@pytest.mark.parametrize("name", sorted(interfaces.SERVICES))
def test_every_service_is_described_as_rosidl_describes_one(name):
    desc = type_hash.description(name)
    top = [(f["name"], f["type"]["nested_type_name"]) for f in desc["type_description"]["fields"]]
    assert top == [
        ("request_message", f"{name}_Request"),
        ("response_message", f"{name}_Response"),
        ("event_message", f"{name}_Event"),
    ]
    names = [d["type_name"] for d in desc["referenced_type_descriptions"]]
    assert names == sorted(names)
    assert {"service_msgs/msg/ServiceEventInfo", "builtin_interfaces/msg/Time"} <= set(names)
    event = next(
        d for d in desc["referenced_type_descriptions"] if d["type_name"].endswith("_Event")
    )
    # at most one request and one response: a bounded sequence (96) of a nested type (1)
    assert [f["type"]["type_id"] for f in event["fields"]] == [1, 97, 97]
    assert type_hash.type_hash(name).startswith("RIHS01_")


def test_cdr_read_back_by_rosbags_and_rosbags_read_by_ours():
    store = _rosbags_store()
    name = "trajectory_msgs/msg/JointTrajectory"
    msg = {
        "header": {"stamp": {"sec": 3, "nanosec": 4}, "frame_id": "base"},
        "joint_names": ["a", "b"],
        "points": [{"positions": [0.5, -0.25], "time_from_start": {"sec": 1, "nanosec": 2}}],
    }
    data = cdr.encoder(name, interfaces.definition_text(name))(msg)
    theirs = store.deserialize_cdr(data, name)
    assert list(theirs.joint_names) == ["a", "b"]
    assert list(theirs.points[0].positions) == [0.5, -0.25]
    assert theirs.points[0].time_from_start.nanosec == 2
    back = cdr.decoder(name, interfaces.definition_text(name))(store.serialize_cdr(theirs, name))
    assert back["points"][0]["positions"] == [0.5, -0.25]
    assert back["header"]["frame_id"] == "base"


def test_cdr_that_is_cut_short_or_big_endian_is_refused():
    name = "std_msgs/msg/Float64MultiArray"
    enc = cdr.encoder(name, interfaces.definition_text(name))
    dec = cdr.decoder(name, interfaces.definition_text(name))
    data = enc({"data": [1.0, 2.0]})
    assert dec(data)["data"] == [1.0, 2.0]
    for bad in (data[:-3], b"\x00\x00\x00\x00" + data[4:], data[:12] + b"\xff\xff\xff\x7f"):
        with pytest.raises(ValueError):
            dec(bad)


def test_an_actions_status_array_read_back_by_rosbags():
    # the action's status topic: goal ids (16 bytes), stamps and int8 statuses in CDR
    store = _rosbags_store()
    name = "action_msgs/msg/GoalStatusArray"
    goal = {"goal_id": {"uuid": list(range(16))}, "stamp": {"sec": 5, "nanosec": 6}}
    msg = {"status_list": [{"goal_info": goal, "status": 4}, {"goal_info": goal, "status": 2}]}
    theirs = store.deserialize_cdr(cdr.encoder(name, interfaces.definition_text(name))(msg), name)
    assert [s.status for s in theirs.status_list] == [4, 2]
    assert theirs.status_list[0].goal_info.goal_id.uuid.tolist() == list(range(16))
    assert theirs.status_list[1].goal_info.stamp.nanosec == 6


# published by ROS 2 (action_msgs' CancelGoal.json as installed, and `ros2 action info -v`)
CANCEL_GOAL_HASH = "RIHS01_573d8b0a534451d7bc2ac8c5ffde8ac14b8593b7001175d0cd6516dcbeb8689a"


def test_an_actions_services_hashes_and_dds_names():
    assert type_hash.type_hash("action_msgs/srv/CancelGoal") == CANCEL_GOAL_HASH
    action = "control_msgs/action/FollowJointTrajectory"
    assert keyexpr.dds_type_name(f"{action}_SendGoal") == (
        "control_msgs::action::dds_::FollowJointTrajectory_SendGoal_"
    )
    # SendGoal's request and GetResult's response carry the action's own messages, each
    # hashed as rosbags hashes it (the parametrized test above)
    desc = type_hash.description(f"{action}_SendGoal")
    names = {d["type_name"] for d in desc["referenced_type_descriptions"]}
    assert {f"{action}_Goal", "unique_identifier_msgs/msg/UUID"} <= names
    desc = type_hash.description(f"{action}_GetResult")
    response = next(
        d
        for d in desc["referenced_type_descriptions"]
        if d["type_name"] == f"{action}_GetResult_Response"
    )
    assert [(f["name"], f["type"]["nested_type_name"]) for f in response["fields"]] == [
        ("status", ""),
        ("result", f"{action}_Result"),
    ]


# action_tutorials_interfaces' Fibonacci (ROS 2's action tutorial): the hashes of its
# SendGoal and GetResult services and its FeedbackMessage as ROS 2 Jazzy builds them
FIBONACCI = "action_tutorials_interfaces/action/Fibonacci"
FIBONACCI_HASHES = {
    "_SendGoal": "RIHS01_a0603060ed69fe2dfbd1a6f3b982a1749957ef346e4a4d2b311a05e305ec37bb",
    "_GetResult": "RIHS01_8b47e383f1e31f6d8df6417ab54957e7d5ea24dad315646ad711ac3fdea81d58",
    "_FeedbackMessage": "RIHS01_50fc26b9cac313652ecbeab3adf9b5414d59fd4d4d5f9058ddcc7525169927f1",
}


def test_an_actions_parts_hash_as_ros_2_hashes_them(monkeypatch):
    messages, services = interfaces.action_parts(
        FIBONACCI, "int32 order", "int32[] sequence", "int32[] partial_sequence"
    )
    for name, text in messages.items():
        monkeypatch.setitem(interfaces.MESSAGES, name, text)
    for name, halves in services.items():
        monkeypatch.setitem(interfaces.SERVICES, name, halves)
    for part, expected in FIBONACCI_HASHES.items():
        assert type_hash.type_hash(FIBONACCI + part) == expected
