// Precompresses the built frontend (`npm run build` runs it after `vite build`): next to every
// text asset worth compressing, `NAME.gz` (gzip, level 9) and `NAME.br` (brotli, quality 11),
// both with Node's own zlib. The service sends one of them with `Content-Encoding` when the
// browser accepts it (backend/src/cobot_hmi/service/static_files.py), so nothing is compressed
// per request and the largest settings cost nothing at run time.
//
//   node scripts/precompress.mjs [DIR]   (DIR: dist by default)
import { readdirSync, readFileSync, statSync, writeFileSync } from "node:fs";
import { join, resolve } from "node:path";
import { brotliCompressSync, constants, gzipSync } from "node:zlib";

const COMPRESSIBLE = /\.(js|mjs|css|html|json|svg|txt|map|wasm)$/i;
/** Below this a compressed copy saves less than its own overhead (one TCP segment). */
const MIN_BYTES = 1024;

const root = resolve(process.argv[2] ?? "dist");

function* files(dir) {
  for (const name of readdirSync(dir)) {
    const path = join(dir, name);
    if (statSync(path).isDirectory()) yield* files(path);
    else yield path;
  }
}

let before = 0;
let afterGzip = 0;
let afterBrotli = 0;
for (const path of files(root)) {
  if (!COMPRESSIBLE.test(path)) continue;
  const data = readFileSync(path);
  if (data.length < MIN_BYTES) continue;
  const gz = gzipSync(data, { level: 9 });
  const br = brotliCompressSync(data, {
    params: {
      [constants.BROTLI_PARAM_QUALITY]: constants.BROTLI_MAX_QUALITY,
      [constants.BROTLI_PARAM_MODE]: constants.BROTLI_MODE_TEXT,
      [constants.BROTLI_PARAM_SIZE_HINT]: data.length,
    },
  });
  writeFileSync(`${path}.gz`, gz);
  writeFileSync(`${path}.br`, br);
  before += data.length;
  afterGzip += gz.length;
  afterBrotli += br.length;
}
const kb = (n) => `${(n / 1024).toFixed(0)} kB`;
console.log(`precompressed ${root}: ${kb(before)} → gzip ${kb(afterGzip)}, brotli ${kb(afterBrotli)}`);
