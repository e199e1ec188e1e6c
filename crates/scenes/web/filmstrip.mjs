// Renders a replay page's contact sheet in headless Chromium (`repertoire replay FILE.rec
// --filmstrip OUT.png` runs it):
//   node crates/scenes/web/filmstrip.mjs PAGE.html OUT.png FRAMES VIEW COLUMNS TILE_W TILE_H
// The page draws FRAMES evenly spaced frames from VIEW (side, front or top) into one PNG
// (window.__replay.filmstrip, crates/scenes/assets/replay/replay.js); this writes it to OUT.png through
// a temporary file. Uses playwright-core from this folder's node_modules and /usr/bin/chromium
// (or $CHROMIUM), both installed by scripts/setup.sh. Exits 1 with the reason on failure.

import { renameSync, writeFileSync } from 'node:fs';
import { resolve } from 'node:path';
import { pathToFileURL } from 'node:url';
import { open } from './chromium.mjs';

const [page_path, out_path, frames, view, columns, tile_w, tile_h] = process.argv.slice(2);
if (!tile_h) {
  console.error('usage: node filmstrip.mjs PAGE.html OUT.png FRAMES VIEW COLUMNS TILE_W TILE_H');
  process.exit(2);
}
const { browser, close } = await open();
let code = 0;
try {
  const page = browser.pages()[0] || (await browser.newPage());
  const problems = [];
  page.on('pageerror', (e) => problems.push(e.message));
  await page.goto(pathToFileURL(resolve(page_path)).href);
  await page.waitForFunction(() => window.__replay && window.__replay.ready && window.__replay.drawn > 1, null,
    { timeout: 60_000 });
  const url = await page.evaluate(
    ([n, v, c, w, h]) => window.__replay.filmstrip(n, v, c, w, h),
    [Number(frames), view, Number(columns), Number(tile_w), Number(tile_h)],
  );
  if (problems.length) throw new Error(problems.join('; '));
  const png = Buffer.from(url.slice(url.indexOf(',') + 1), 'base64');
  const tmp = `${out_path}.tmp`;
  writeFileSync(tmp, png);
  renameSync(tmp, out_path);
  console.log(JSON.stringify({ out: out_path, bytes: png.length }));
} catch (e) {
  console.error(`filmstrip: ${e.message}`);
  code = 1;
} finally {
  await close();
}
process.exit(code);
