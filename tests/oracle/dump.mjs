// Reads a bag with the libraries Foxglove itself runs and prints every message as one JSON line, for driftlab's
// tests to compare with what driftlab reads (tests/formats/oracle_test.cc):
//   node dump.mjs FILE        FILE: an MCAP file, a ROS 1 bag, or a rosbag2 sqlite3 file (.db3)
// Each line: {"topic", "type", "encoding", "time_ns" (the recorder's receive time), "sequence" (MCAP), "msg"}.
// MCAP files are read twice: front to back with McapStreamReader (CRCs checked) and through their summary and
// indexes with McapIndexedReader; both must find the same messages, or the file's index is wrong (exit 1).
// ROS 1 bags: @foxglove/rosbag (bz2 and lz4 chunks with Foxglove's wasm decoders); sqlite3: the sqlite3 program
// reads the rows (Node 20 has no sqlite), @foxglove/rosmsg2-serialization decodes them.
import { execFileSync } from "node:child_process";
import { readFileSync, openSync, readSync, fstatSync } from "node:fs";
import { resolve } from "node:path";

import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { parse as parseDefinition } from "@foxglove/rosmsg";
import { MessageReader as Ros1Reader } from "@foxglove/rosmsg-serialization";
import { MessageReader as Ros2Reader } from "@foxglove/rosmsg2-serialization";
import { Bag } from "@foxglove/rosbag";
import { FileReader } from "@foxglove/rosbag/node.js";
import Bzip2 from "@foxglove/wasm-bz2";
import lz4 from "@foxglove/wasm-lz4";
import * as zstd from "@foxglove/wasm-zstd";

const file = process.argv[2];
if (!file) {
  console.error("usage: node dump.mjs FILE");
  process.exit(2);
}
await zstd.isLoaded;
await lz4.isLoaded;
const bzip2 = await Bzip2.init();

/// JSON with BigInts as exact numbers and typed arrays as arrays.
function json(value) {
  const text = JSON.stringify(value, (_k, v) => {
    if (typeof v === "bigint") return `__big__${v.toString()}__`;
    if (ArrayBuffer.isView(v)) return Array.from(v, (x) => (typeof x === "bigint" ? `__big__${x}__` : x));
    return v;
  });
  return text.replace(/"__big__(-?\d+)__"/g, "$1");
}

const out = [];
function emit(topic, type, encoding, timeNs, sequence, msg) {
  out.push(json({ topic, type, encoding, time_ns: BigInt(timeNs), sequence, msg }));
}

const readers = new Map();
function decoder(type, encoding, schemaEncoding, schemaData) {
  const key = `${type}\u0000${encoding}\u0000${schemaEncoding}\u0000${schemaData}`;
  let d = readers.get(key);
  if (d) return d;
  if (encoding === "cdr" && schemaEncoding === "ros2msg") {
    const r = new Ros2Reader(parseDefinition(schemaData, { ros2: true }));
    d = (bytes) => r.readMessage(bytes);
  } else if (encoding === "ros1" && (schemaEncoding === "ros1msg" || schemaEncoding === "")) {
    const r = new Ros1Reader(parseDefinition(schemaData));
    d = (bytes) => r.readMessage(bytes);
  } else if (encoding === "json") {
    const text = new TextDecoder();
    d = (bytes) => JSON.parse(text.decode(bytes));
  } else {
    d = () => null;  // an encoding these libraries do not decode
  }
  readers.set(key, d);
  return d;
}

const decompressHandlers = {
  zstd: (buffer, size) => zstd.decompress(buffer, Number(size)),
  lz4: (buffer, size) => lz4(buffer, Number(size)),
};

function isZstd(b) {
  return b.length >= 4 && b[0] === 0x28 && b[1] === 0xb5 && b[2] === 0x2f && b[3] === 0xfd;
}

/// A zstd frame whose size is not in its header (rosbag2's compressed files): grown until it fits.
function unzstd(b) {
  for (let size = b.length * 8; ; size *= 2) {
    try {
      return zstd.decompress(b, size);
    } catch (e) {
      if (size > 1 << 30) throw e;
    }
  }
}

async function dumpMcap(bytes) {
  const stream = new McapStreamReader({ validateCrcs: true, decompressHandlers });
  stream.append(bytes);
  const schemas = new Map();
  const channels = new Map();
  const seen = [];
  for (let rec; (rec = stream.nextRecord()); ) {
    if (rec.type === "Schema") schemas.set(rec.id, rec);
    else if (rec.type === "Channel") channels.set(rec.id, rec);
    else if (rec.type === "Message") {
      const ch = channels.get(rec.channelId);
      const sc = schemas.get(ch.schemaId) ?? { name: "", encoding: "", data: new Uint8Array() };
      const def = new TextDecoder().decode(sc.data);
      const msg = decoder(sc.name, ch.messageEncoding, sc.encoding, def)(rec.data);
      emit(ch.topic, sc.name, ch.messageEncoding, rec.logTime, rec.sequence, msg);
      seen.push(`${rec.channelId}/${rec.logTime}/${rec.sequence}`);
    }
  }
  if (!stream.done()) throw new Error("the MCAP stream ends early");
  // The same messages through the summary and the indexes, when the file has them.
  let indexed;
  try {
    indexed = await McapIndexedReader.Initialize({
      readable: {
        size: async () => BigInt(bytes.length),
        read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
      },
      decompressHandlers,
    });
  } catch (e) {
    if (String(e).includes("summary")) return;  // a file without a summary: nothing to check
    throw e;
  }
  if (indexed.chunkIndexes.length === 0 && seen.length > 0) return;  // messages outside chunks: not indexed
  const found = [];
  for await (const m of indexed.readMessages()) found.push(`${m.channelId}/${m.logTime}/${m.sequence}`);
  const a = [...seen].sort().join("\n");
  const b = found.sort().join("\n");
  if (a !== b) throw new Error(`the indexes find ${found.length} messages, the stream ${seen.length}`);
  const stats = indexed.statistics;
  if (stats && Number(stats.messageCount) !== seen.length) {
    throw new Error(`the statistics count ${stats.messageCount} messages, the file holds ${seen.length}`);
  }
}

async function dumpRos1(path) {
  const bag = new Bag(new FileReader(path), {
    decompress: {
      bz2: (buffer, size) => bzip2.decompress(buffer, size, { small: false }),
      lz4: (buffer, size) => lz4(buffer, size),
    },
    parse: false,
  });
  await bag.open();
  for await (const m of bag.messageIterator()) {
    const c = bag.connections.get(m.connectionId);
    const msg = decoder(c.type, "ros1", "ros1msg", c.messageDefinition)(m.data);
    const ns = BigInt(m.timestamp.sec) * 1000000000n + BigInt(m.timestamp.nsec);
    emit(m.topic, c.type, "ros1", ns, null, msg);
  }
}

function dumpSqlite(path) {
  // Immutable (as a URI): a read-only connection to a bag in WAL mode leaves an empty -wal and a -shm file beside
  // it, which wrote into ../shared/data/bags. The bags read here are finished recordings, with no log to see.
  const uri = "file:" + resolve(path).replace(/[%?#]/g, (c) => "%" + c.charCodeAt(0).toString(16)) + "?immutable=1";
  const q = (sql) =>
    JSON.parse(execFileSync("sqlite3", ["-readonly", "-json", uri, sql], { maxBuffer: 1 << 30 }).toString() || "[]");
  const tables = new Set(q("SELECT name FROM sqlite_master WHERE type = 'table'").map((r) => r.name));
  const defs = new Map();
  if (tables.has("message_definitions")) {
    for (const r of q("SELECT topic_type, encoding, encoded_message_definition AS d FROM message_definitions")) {
      defs.set(r.topic_type, r);
    }
  }
  const rows = q(
    "SELECT t.name AS topic, t.type AS type, t.serialization_format AS enc, m.timestamp AS ts, hex(m.data) AS data " +
      "FROM messages m JOIN topics t ON m.topic_id = t.id ORDER BY m.id",
  );
  // sqlite3 prints integers as JSON numbers: timestamps need BigInt precision, so they are read again as text.
  const stamps = q("SELECT CAST(timestamp AS TEXT) AS ts FROM messages ORDER BY id").map((r) => BigInt(r.ts));
  rows.forEach((r, i) => {
    let data = Uint8Array.from(Buffer.from(r.data, "hex"));
    if (isZstd(data)) data = unzstd(data);
    const d = defs.get(r.type);
    const msg = d ? decoder(r.type, r.enc, d.encoding, d.d)(data) : null;
    emit(r.topic, r.type, r.enc, stamps[i], null, msg);
  });
}

let bytes = readFileSync(file);
if (isZstd(bytes)) bytes = unzstd(bytes);  // rosbag2's file compression
const head = bytes.subarray(0, 16).toString("latin1");
if (head.startsWith("\x89MCAP")) {
  await dumpMcap(bytes);
} else if (head.startsWith("#ROSBAG V2.0")) {
  await dumpRos1(file);
} else if (head.startsWith("SQLite format 3")) {
  dumpSqlite(file);
} else {
  console.error(`${file}: not a file this oracle reads`);
  process.exit(2);
}
process.stdout.write(out.join("\n") + (out.length ? "\n" : ""));
