// The npm readers' speed on a bag (scripts/bench import): every message read and decoded the way Foxglove does it,
// nothing printed but the count. MCAP with McapStreamReader (CRCs checked, as driftlab checks them) and
// @foxglove/rosmsg2-serialization; ROS 1 bags with @foxglove/rosbag and @foxglove/rosmsg-serialization.
//   node bench_read.mjs FILE
import { readFileSync } from "node:fs";

import { McapStreamReader } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageReader as Ros1Reader } from "@foxglove/rosmsg-serialization";
import { MessageReader as Ros2Reader } from "@foxglove/rosmsg2-serialization";
import { Bag } from "@foxglove/rosbag";
import { FileReader } from "@foxglove/rosbag/node.js";
import Bzip2 from "@foxglove/wasm-bz2";
import lz4 from "@foxglove/wasm-lz4";
import * as zstd from "@foxglove/wasm-zstd";

await zstd.isLoaded;
await lz4.isLoaded;
const bzip2 = await Bzip2.init();
const file = process.argv[2];
let count = 0;
const head = readFileSync(file, { length: 16 }).subarray(0, 16).toString("latin1");
if (head.startsWith("\x89MCAP")) {
  const s = new McapStreamReader({
    validateCrcs: true,
    decompressHandlers: {
      zstd: (b, n) => zstd.decompress(b, Number(n)),
      lz4: (b, n) => lz4(b, Number(n)),
    },
  });
  s.append(readFileSync(file));
  const schemas = new Map(), readers = new Map();
  for (let r; (r = s.nextRecord()); ) {
    if (r.type === "Schema") schemas.set(r.id, r);
    else if (r.type === "Channel") {
      const sc = schemas.get(r.schemaId);
      readers.set(r.id, new Ros2Reader(parse(new TextDecoder().decode(sc.data), { ros2: true })));
    } else if (r.type === "Message") {
      readers.get(r.channelId).readMessage(r.data);
      ++count;
    }
  }
} else {
  const bag = new Bag(new FileReader(file), {
    decompress: { bz2: (b, n) => bzip2.decompress(b, n, { small: false }), lz4: (b, n) => lz4(b, n) },
    parse: false,
  });
  await bag.open();
  const readers = new Map();
  for await (const m of bag.messageIterator()) {
    let r = readers.get(m.connectionId);
    if (!r) {
      r = new Ros1Reader(parse(bag.connections.get(m.connectionId).messageDefinition));
      readers.set(m.connectionId, r);
    }
    r.readMessage(m.data);
    ++count;
  }
}
console.log(count);
