// Reads a PX4 ULog with Foxglove's own reader (@foxglove/ulog) and prints, as one JSON object, what driftlab's
// import is compared with (tests/formats/ulog_test.cc):
//   node dump_ulog.mjs FILE.ulg
// {"start_us", "topics": {CHANNEL: {"count", "first_us", "last_us"}}, "logs", "tagged_logs", "dropouts_ms": [...],
//  "gnss_utc": [[boot_us, utc_us], ...]}
// gnss_utc: every sensor_gps / vehicle_gps_position message with a 3D fix (fix_type 3 and up) and a UTC time
// (time_utc_usec, not 0), the boot time of that UTC time as PX4 defines it: timestamp + timestamp_time_relative.
// A channel is named as driftlab names it: the topic's name when it is logged in one instance, 0, else
// "name/multi_id". first_us and last_us are the smallest and largest `timestamp` of the topic's messages (the
// reader yields them in time order, not in file order).
import { ULog, MessageType } from "@foxglove/ulog";
import { FileReader } from "@foxglove/ulog/node.js";

const file = process.argv[2];
if (!file) {
  console.error("usage: node dump_ulog.mjs FILE.ulg");
  process.exit(2);
}
const ulog = new ULog(new FileReader(file));
await ulog.open();

const perId = new Map();  // msgId -> {count, first, last}
let logs = 0;
let taggedLogs = 0;
const dropouts = [];
const gnssUtc = [];
for await (const msg of ulog.readMessages()) {
  if (msg.type === MessageType.Data) {
    const t = msg.value.timestamp;
    const s = perId.get(msg.msgId) ?? { count: 0, first: t, last: t };
    s.count += 1;
    if (t < s.first) s.first = t;
    if (t > s.last) s.last = t;
    perId.set(msg.msgId, s);
    const name = ulog.subscriptions.get(msg.msgId)?.name;
    const v = msg.value;
    if ((name === "sensor_gps" || name === "vehicle_gps_position") && v.fix_type >= 3 && v.time_utc_usec > 0n) {
      gnssUtc.push([Number(t + BigInt(v.timestamp_time_relative ?? 0)), Number(v.time_utc_usec)]);
    }
  } else if (msg.type === MessageType.Log) {
    logs += 1;
  } else if (msg.type === MessageType.LogTagged) {
    taggedLogs += 1;
  } else if (msg.type === MessageType.Dropout) {
    dropouts.push(msg.duration);
  }
}

const instances = new Map();  // topic name -> set of multi ids with data
for (const [id] of perId) {
  const sub = ulog.subscriptions.get(id);
  if (!instances.has(sub.name)) instances.set(sub.name, new Set());
  instances.get(sub.name).add(sub.multiId);
}
const topics = {};
for (const [id, s] of perId) {
  const sub = ulog.subscriptions.get(id);
  const ids = instances.get(sub.name);
  const plain = ids.size === 1 && ids.has(0);
  const channel = plain ? sub.name : `${sub.name}/${sub.multiId}`;
  const prev = topics[channel];
  if (prev) {
    // Two subscriptions to one instance (a msg_id subscribed again): one channel.
    prev.count += s.count;
    if (s.first < BigInt(prev.first_us)) prev.first_us = Number(s.first);
    if (s.last > BigInt(prev.last_us)) prev.last_us = Number(s.last);
  } else {
    topics[channel] = { count: s.count, first_us: Number(s.first), last_us: Number(s.last) };
  }
}
console.log(JSON.stringify({
  start_us: Number(ulog.header.timestamp),
  topics,
  logs,
  tagged_logs: taggedLogs,
  dropouts_ms: dropouts,
  gnss_utc: gnssUtc,
}));
