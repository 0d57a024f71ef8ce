// The Khronos glTF validator over the files named on the command line: one JSON line
// each, {"path", "errors", "warnings", "messages"} (messages: the errors, code and
// pointer; resources: each buffer and image with its storage, "external" for a separate
// file, and its uri). External buffers and images are read beside the file. Exit 0 unless a file
// could not be validated at all (then exit 2); the caller judges the counts.
"use strict";
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

async function one(file) {
  const full = path.resolve(file);
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(full)), {
    uri: path.basename(full),
    maxIssues: 50,
    externalResourceFunction: (uri) =>
      fs.promises.readFile(path.resolve(path.dirname(full), decodeURIComponent(uri))),
  });
  const issues = report.issues;
  const messages = issues.messages
    .filter((m) => m.severity === 0)
    .map((m) => `${m.code} ${m.pointer || ""}: ${m.message}`);
  const resources = ((report.info && report.info.resources) || []).map((r) => ({
    pointer: r.pointer,
    storage: r.storage,
    uri: r.uri,
  }));
  return {
    path: file,
    errors: issues.numErrors,
    warnings: issues.numWarnings,
    messages,
    resources,
  };
}

(async () => {
  let failed = 0;
  for (const file of process.argv.slice(2)) {
    try {
      console.log(JSON.stringify(await one(file)));
    } catch (err) {
      failed += 1;
      console.log(JSON.stringify({ path: file, errors: -1, messages: [String(err)] }));
    }
  }
  process.exit(failed ? 2 : 0);
})();
