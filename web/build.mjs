// Build the editor's front end into src/retime/editor/static/ (committed: users need no npm).
import { build, context } from "esbuild";
import { copyFileSync, mkdirSync, readdirSync, rmSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const out = join(here, "..", "src", "retime", "editor", "static");
const watch = process.argv.includes("--watch");

mkdirSync(out, { recursive: true });
for (const f of readdirSync(out)) if (!f.startsWith(".")) rmSync(join(out, f));

const options = {
  entryPoints: { app: join(here, "src", "main.js") },
  bundle: true,
  format: "esm",
  target: ["es2020"],
  minify: !watch,
  legalComments: "linked",
  outdir: out,
  logLevel: "info",
};
copyFileSync(join(here, "index.html"), join(out, "index.html"));
copyFileSync(join(here, "favicon.svg"), join(out, "favicon.svg"));
if (watch) await (await context(options)).watch();
else await build(options);
