// Writes an MCAP file of ROS messages with the libraries Foxglove itself runs (@mcap/core's McapWriter,
// @foxglove/rosmsg2-serialization or @foxglove/rosmsg-serialization), independently of driftlab's writer, for the
// import tests to check driftlab's reading against the values written (tests/formats/oracle_test.cc):
//   node write_mcap.mjs SPEC.json OUT.mcap
// SPEC: {"profile": "ros2" (CDR, ros2msg schemas) or "ros1" (ROS 1 serialization, ros1msg schemas),
//        "compression": "zstd" or "none",
//        "messages": [{"topic", "type" ("sensor_msgs/msg/Imu" or "sensor_msgs/Imu"), "time_ns", "sequence", "msg"}],
//        "definitions": {"pkg/Type": ".msg text"} (optional: another release's definition of a type)}
// A number that JSON cannot hold is written as a string: "NaN", "Infinity", "-Infinity", a 64-bit integer "12n". The definitions are this
// file's own (below): the fields of the standard messages as ROS 1 and ROS 2 define them.
import { openSync, readFileSync, writeSync, closeSync } from "node:fs";

import { McapWriter } from "@mcap/core";
import { parse as parseDefinition } from "@foxglove/rosmsg";
import { MessageWriter as Ros1Writer } from "@foxglove/rosmsg-serialization";
import { MessageWriter as Ros2Writer } from "@foxglove/rosmsg2-serialization";
import * as zstd from "@foxglove/wasm-zstd";

const [specFile, outFile] = process.argv.slice(2);
if (!specFile || !outFile) {
  console.error("usage: node write_mcap.mjs SPEC.json OUT.mcap");
  process.exit(2);
}
await zstd.isLoaded;

// The types' fields, "pkg/Type" -> definition; Header and time differ between ROS 1 and ROS 2.
const COMMON = {
  "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
  "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z\n",
  "geometry_msgs/Quaternion": "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n",
  "geometry_msgs/Pose": "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
  "geometry_msgs/PoseStamped": "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
  "geometry_msgs/Transform": "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n",
  "geometry_msgs/TransformStamped":
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n",
  "geometry_msgs/Twist": "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n",
  "sensor_msgs/Imu":
    "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n" +
    "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n" +
    "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
  "sensor_msgs/Image":
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\n" +
    "uint8[] data\n",
  "sensor_msgs/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data\n",
  "sensor_msgs/JointState":
    "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
  "sensor_msgs/NavSatStatus":
    "int8 STATUS_NO_FIX=-1\nint8 STATUS_FIX=0\nint8 STATUS_SBAS_FIX=1\nint8 STATUS_GBAS_FIX=2\nint8 status\n" +
    "uint16 SERVICE_GPS=1\nuint16 SERVICE_GLONASS=2\nuint16 SERVICE_COMPASS=4\nuint16 SERVICE_GALILEO=8\n" +
    "uint16 service\n",
  "sensor_msgs/NavSatFix":
    "std_msgs/Header header\nsensor_msgs/NavSatStatus status\nfloat64 latitude\nfloat64 longitude\n" +
    "float64 altitude\nfloat64[9] position_covariance\nuint8 COVARIANCE_TYPE_UNKNOWN=0\n" +
    "uint8 COVARIANCE_TYPE_APPROXIMATED=1\nuint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2\nuint8 COVARIANCE_TYPE_KNOWN=3\n" +
    "uint8 position_covariance_type\n",
  "sensor_msgs/MagneticField":
    "std_msgs/Header header\ngeometry_msgs/Vector3 magnetic_field\nfloat64[9] magnetic_field_covariance\n",
  "sensor_msgs/FluidPressure": "std_msgs/Header header\nfloat64 fluid_pressure\nfloat64 variance\n",
  "sensor_msgs/LaserScan":
    "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n" +
    "float32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\nfloat32[] ranges\n" +
    "float32[] intensities\n",
  "geometry_msgs/PoseWithCovariance": "geometry_msgs/Pose pose\nfloat64[36] covariance\n",
  "geometry_msgs/PoseWithCovarianceStamped": "std_msgs/Header header\ngeometry_msgs/PoseWithCovariance pose\n",
  "geometry_msgs/TwistWithCovariance": "geometry_msgs/Twist twist\nfloat64[36] covariance\n",
  "nav_msgs/Odometry":
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n" +
    "geometry_msgs/TwistWithCovariance twist\n",
  "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
  "trajectory_msgs/JointTrajectory":
    "std_msgs/Header header\nstring[] joint_names\ntrajectory_msgs/JointTrajectoryPoint[] points\n",
  "mavros_msgs/State":
    "std_msgs/Header header\nbool connected\nbool armed\nbool guided\nbool manual_input\nstring mode\n" +
    "uint8 system_status\n",
  "mavros_msgs/TimesyncStatus":
    "std_msgs/Header header\nuint64 remote_timestamp_ns\nint64 observed_offset_ns\nint64 estimated_offset_ns\n" +
    "float32 round_trip_time_ms\n",
};
const POINT = "float64[] positions\nfloat64[] velocities\nfloat64[] accelerations\nfloat64[] effort\n";
const TRAJECTORY_POINT = "trajectory_msgs/JointTrajectoryPoint";
// A joint trajectory controller's state: ROS 1 and ROS 2 before Humble (desired, actual, error).
const CONTROLLER_STATE_V1 =
  "std_msgs/Header header\nstring[] joint_names\n" +
  ["desired", "actual", "error"].map((f) => `${TRAJECTORY_POINT} ${f}\n`).join("");
const ROS2 = {
  ...COMMON,
  "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
  "builtin_interfaces/Time": "int32 sec\nuint32 nanosec\n",
  "builtin_interfaces/Duration": "int32 sec\nuint32 nanosec\n",
  "rosgraph_msgs/Clock": "builtin_interfaces/Time clock\n",
  "trajectory_msgs/JointTrajectoryPoint": POINT + "builtin_interfaces/Duration time_from_start\n",
  "trajectory_msgs/MultiDOFJointTrajectoryPoint":
    "geometry_msgs/Transform[] transforms\ngeometry_msgs/Twist[] velocities\ngeometry_msgs/Twist[] accelerations\n" +
    "builtin_interfaces/Duration time_from_start\n",
  // control_msgs 4 (Humble): reference, feedback, error, output, the deprecated desired and actual, then the
  // multi-DOF points. A spec's "definitions" replaces it with another release's (Jazzy drops desired and actual).
  "control_msgs/JointTrajectoryControllerState":
    "std_msgs/Header header\nstring[] joint_names\n" +
    ["reference", "feedback", "error", "output", "desired", "actual"].map((f) => `${TRAJECTORY_POINT} ${f}\n`).join("") +
    "string[] multi_dof_joint_names\n" +
    ["reference", "feedback", "error", "output", "desired", "actual"]
      .map((f) => `trajectory_msgs/MultiDOFJointTrajectoryPoint multi_dof_${f}\n`)
      .join(""),
};
const ROS1 = {
  ...COMMON,
  "std_msgs/Header": "uint32 seq\ntime stamp\nstring frame_id\n",
  "rosgraph_msgs/Clock": "time clock\n",
  "trajectory_msgs/JointTrajectoryPoint": POINT + "duration time_from_start\n",
  // MoveIt's hand-over to a ROS 1 controller: an actionlib goal.
  "control_msgs/FollowJointTrajectoryActionGoal":
    "std_msgs/Header header\nactionlib_msgs/GoalID goal_id\ncontrol_msgs/FollowJointTrajectoryGoal goal\n",
  "actionlib_msgs/GoalID": "time stamp\nstring id\n",
  "control_msgs/FollowJointTrajectoryGoal":
    "trajectory_msgs/JointTrajectory trajectory\ncontrol_msgs/JointTolerance[] path_tolerance\n" +
    "control_msgs/JointTolerance[] goal_tolerance\nduration goal_time_tolerance\n",
  "control_msgs/JointTolerance": "string name\nfloat64 position\nfloat64 velocity\nfloat64 acceleration\n",
  "control_msgs/JointTrajectoryControllerState": CONTROLLER_STATE_V1,
};

/// The full definition of a type: its text, then each type it uses after a line of '=' and "MSG: pkg/Type".
function fullDefinition(defs, name, ros2) {
  const seen = new Set([name]);
  let out = defs[name];
  const visit = (text) => {
    for (const line of text.split("\n")) {
      const type = line.split(/\s+/)[0].replace(/\[.*\]$/, "");
      if (!type.includes("/") || seen.has(type)) continue;
      seen.add(type);
      const t = defs[type];
      if (t === undefined) throw new Error(`no definition of ${type}`);
      out += "=".repeat(80) + "\nMSG: " + type + "\n" + t;
      visit(t);
    }
  };
  visit(out);
  return out;
}

/// JSON values as the writers take them: "NaN" and the infinities as numbers, byte arrays as Uint8Array, 64-bit
/// integers (written as strings ending in "n": "-1500000000n") as BigInt.
function revive(value, key) {
  if (typeof value === "string" && /^-?[0-9]+n$/.test(value)) return BigInt(value.slice(0, -1));
  if (value === "NaN") return NaN;
  if (value === "Infinity") return Infinity;
  if (value === "-Infinity") return -Infinity;
  if (Array.isArray(value)) {
    if (key === "data") return Uint8Array.from(value);
    return value.map((v) => revive(v, ""));
  }
  if (value && typeof value === "object") {
    const o = {};
    for (const [k, v] of Object.entries(value)) o[k] = revive(v, k);
    return o;
  }
  return value;
}

const spec = JSON.parse(readFileSync(specFile, "utf8"));
const ros2 = spec.profile === "ros2";
const defs = { ...(ros2 ? ROS2 : ROS1), ...(spec.definitions ?? {}) };
const fd = openSync(outFile, "w");
let position = 0n;
const writer = new McapWriter({
  writable: {
    write: async (buffer) => {
      writeSync(fd, buffer);
      position += BigInt(buffer.byteLength);
    },
    position: () => position,
  },
  chunkSize: 64 * 1024,
  compressChunk:
    spec.compression === "zstd"
      ? (data) => ({ compression: "zstd", compressedData: zstd.compress(data, 1) })
      : undefined,
});
await writer.start({ profile: ros2 ? "ros2" : "ros1", library: "write_mcap.mjs" });
const channels = new Map();
for (const m of spec.messages) {
  const base = m.type.replace("/msg/", "/");
  let ch = channels.get(m.topic);
  if (!ch) {
    const text = fullDefinition(defs, base, ros2);
    const parsed = parseDefinition(text, { ros2 });
    const schemaId = await writer.registerSchema({
      name: ros2 ? base.replace("/", "/msg/") : base,
      encoding: ros2 ? "ros2msg" : "ros1msg",
      data: new TextEncoder().encode(text),
    });
    const id = await writer.registerChannel({
      topic: m.topic,
      schemaId,
      messageEncoding: ros2 ? "cdr" : "ros1",
      metadata: new Map(),
    });
    ch = { id, writer: ros2 ? new Ros2Writer(parsed) : new Ros1Writer(parsed) };
    channels.set(m.topic, ch);
  }
  await writer.addMessage({
    channelId: ch.id,
    sequence: m.sequence ?? 0,
    logTime: BigInt(m.time_ns),
    publishTime: BigInt(m.time_ns),
    data: ch.writer.writeMessage(revive(m.msg, "")),
  });
}
await writer.end();
closeSync(fd);
