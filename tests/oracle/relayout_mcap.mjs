// Writes an MCAP file again with Foxglove's own writer (@mcap/core's McapWriter) in another layout, every record
// of it kept (schemas, channels, messages with their times, sequences and bytes, metadata, attachments), for the
// import tests to check that every layout a writer may choose reads as the same recording
// (tests/formats/oracle_test.cc):
//   node relayout_mcap.mjs IN.mcap OUT.mcap LAYOUT.json
// LAYOUT: McapWriter's own options (useChunks, chunkSize, useMessageIndex, useChunkIndex, useStatistics,
//         useSummaryOffsets, repeatSchemas, repeatChannels, useAttachmentIndex, useMetadataIndex,
//         startChannelId), and
//         "compression": "zstd" or "none" (the chunks'),
//         "attachment": {"name", "media_type", "text"} (optional: one more attachment, written first),
//         "metadata": {"name", "entries": {...}} (optional: one more metadata record, written first).
// IN is read front to back with McapStreamReader (its CRCs checked).
import { openSync, readFileSync, writeSync, closeSync } from "node:fs";

import { McapStreamReader, McapWriter } from "@mcap/core";
import * as zstd from "@foxglove/wasm-zstd";

const [inFile, outFile, layoutFile] = process.argv.slice(2);
if (!inFile || !outFile || !layoutFile) {
  console.error("usage: node relayout_mcap.mjs IN.mcap OUT.mcap LAYOUT.json");
  process.exit(2);
}
await zstd.isLoaded;
const layout = JSON.parse(readFileSync(layoutFile, "utf8"));
const { compression, attachment, metadata, ...options } = layout;

const reader = new McapStreamReader({
  decompressHandlers: { zstd: (data, size) => zstd.decompress(data, Number(size)) },
  validateCrcs: true,
});
reader.append(readFileSync(inFile));

const fd = openSync(outFile, "w");
let position = 0n;
const writer = new McapWriter({
  ...options,
  writable: {
    write: async (buffer) => {
      writeSync(fd, buffer);
      position += BigInt(buffer.byteLength);
    },
    position: () => position,
  },
  compressChunk:
    compression === "zstd" ? (data) => ({ compression: "zstd", compressedData: zstd.compress(data, 1) }) : undefined,
});

const text = new TextEncoder();
const schemas = new Map(); // the input's schema id -> the output's
const channels = new Map(); // the input's channel id -> the output's
let started = false;
for (let record; (record = reader.nextRecord()); ) {
  switch (record.type) {
    case "Header":
      await writer.start({ profile: record.profile, library: "relayout_mcap.mjs" });
      started = true;
      if (attachment) {
        await writer.addAttachment({
          name: attachment.name,
          logTime: 0n,
          createTime: 0n,
          mediaType: attachment.media_type,
          data: text.encode(attachment.text),
        });
      }
      if (metadata) await writer.addMetadata({ name: metadata.name, metadata: new Map(Object.entries(metadata.entries)) });
      break;
    case "Schema":
      if (!schemas.has(record.id)) {
        schemas.set(record.id, await writer.registerSchema({ name: record.name, encoding: record.encoding, data: record.data }));
      }
      break;
    case "Channel":
      if (!channels.has(record.id)) {
        if (record.schemaId !== 0 && !schemas.has(record.schemaId)) {
          console.error(`${inFile}: channel ${record.id} before its schema ${record.schemaId}`);
          process.exit(1);
        }
        channels.set(
          record.id,
          await writer.registerChannel({
            topic: record.topic,
            schemaId: record.schemaId === 0 ? 0 : schemas.get(record.schemaId),
            messageEncoding: record.messageEncoding,
            metadata: record.metadata,
          }),
        );
      }
      break;
    case "Message":
      if (!channels.has(record.channelId)) {
        console.error(`${inFile}: a message on channel ${record.channelId}, which no channel record defines`);
        process.exit(1);
      }
      await writer.addMessage({
        channelId: channels.get(record.channelId),
        sequence: record.sequence,
        logTime: record.logTime,
        publishTime: record.publishTime,
        data: record.data,
      });
      break;
    case "Metadata":
      await writer.addMetadata({ name: record.name, metadata: record.metadata });
      break;
    case "Attachment":
      await writer.addAttachment({
        name: record.name,
        logTime: record.logTime,
        createTime: record.createTime,
        mediaType: record.mediaType,
        data: record.data,
      });
      break;
    default:
      break; // indexes, statistics and the summary: the writer makes its own, as the layout asks
  }
}
if (!started || !reader.done()) {
  console.error(`${inFile}: not a whole MCAP file`);
  process.exit(1);
}
await writer.end();
closeSync(fd);
