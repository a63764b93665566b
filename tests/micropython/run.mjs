// Run a MicroPython program in the WebAssembly build of MicroPython under node.
// Usage: node run.mjs <package dir> < job.json
// job.json: {"files": {"/name.py": "source", ...}, "code": "program"}; the
// program's output goes to stdout; a Python exception exits with status 1.
import { readFileSync } from "node:fs";
import { join } from "node:path";
import { pathToFileURL } from "node:url";

const pkg = process.argv[2];
const job = JSON.parse(readFileSync(0, "utf8"));
const { loadMicroPython } = await import(pathToFileURL(join(pkg, "micropython.mjs")).href);
const mp = await loadMicroPython({
  stdout: (line) => process.stdout.write(line + "\n"),
  stderr: (line) => process.stderr.write(line + "\n"),
});
for (const [path, text] of Object.entries(job.files)) {
  mp.FS.writeFile(path, text);
}
try {
  mp.runPython(job.code);
} catch (err) {
  process.stderr.write(String(err && err.message ? err.message : err) + "\n");
  process.exit(1);
}
