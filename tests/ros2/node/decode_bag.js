// Decode every message of a ROS 2 MCAP bag as Foxglove's app does: the ros2msg schema
// parsed by @foxglove/rosmsg (ros2: true), the CDR read by @foxglove/rosmsg2-serialization.
// Usage: node decode_bag.js BAG.mcap  ->  one JSON line on stdout:
//   {"profile", "topics": {topic: {"type", "encoding", "count"}}, "first": {topic: message}}
// Exit 1 (the error on stderr) when a record or a message does not decode.
"use strict";
const fs = require("fs");
const { McapStreamReader } = require("@mcap/core");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");
const { decompress } = require("fzstd");

function plain(value) {
  if (typeof value === "bigint") return value.toString();
  if (ArrayBuffer.isView(value)) return Array.from(value, plain);
  if (Array.isArray(value)) return value.map(plain);
  if (value && typeof value === "object") {
    const out = {};
    for (const [k, v] of Object.entries(value)) out[k] = plain(v);
    return out;
  }
  if (typeof value === "number" && !Number.isFinite(value)) return String(value);
  return value;
}

const reader = new McapStreamReader({
  validateCrcs: true,
  decompressHandlers: { zstd: (buf, size) => decompress(buf, new Uint8Array(Number(size))) },
});
reader.append(fs.readFileSync(process.argv[2]));
const schemas = new Map();
const channels = new Map();
const out = { profile: null, topics: {}, first: {} };
let record;
while ((record = reader.nextRecord()) !== undefined) {
  if (record.type === "Header") out.profile = record.profile;
  else if (record.type === "Schema") schemas.set(record.id, record);
  else if (record.type === "Channel" && !channels.has(record.id)) {
    const schema = schemas.get(record.schemaId);
    if (schema.encoding !== "ros2msg") throw new Error(`${record.topic}: schema ${schema.encoding}`);
    const text = new TextDecoder().decode(schema.data);
    channels.set(record.id, { topic: record.topic, type: schema.name,
      reader: new MessageReader(parse(text, { ros2: true })) });
    out.topics[record.topic] ??= { type: schema.name, encoding: record.messageEncoding, count: 0 };
  } else if (record.type === "Message") {
    const channel = channels.get(record.channelId);
    const message = channel.reader.readMessage(record.data);
    const entry = out.topics[channel.topic];
    if (entry.count++ === 0) out.first[channel.topic] = plain(message);
  }
}
if (!reader.done()) throw new Error("the file ends inside a record");
process.stdout.write(JSON.stringify(out) + "\n");
