// Renders a replay page's contact sheet in headless Chromium (`repertoire replay FILE.rec
// --filmstrip OUT.png` runs it):
//   node scenes/web/filmstrip.mjs PAGE.html OUT.png FRAMES VIEW COLUMNS TILE_W TILE_H
// The page draws FRAMES evenly spaced frames from VIEW (side, front or top) into one PNG
// (window.__replay.filmstrip, scenes/assets/replay/replay.js); this writes it to OUT.png through
// a temporary file. Uses playwright-core from this folder's node_modules and /usr/bin/chromium
// (or $CHROMIUM), both installed by scripts/setup.sh. Exits 1 with the reason on failure.

import { createRequire } from 'node:module';
import { existsSync, mkdtempSync, renameSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const [page_path, out_path, frames, view, columns, tile_w, tile_h] = process.argv.slice(2);
if (!tile_h) {
  console.error('usage: node filmstrip.mjs PAGE.html OUT.png FRAMES VIEW COLUMNS TILE_W TILE_H');
  process.exit(2);
}
const chromium_path = process.env.CHROMIUM || '/usr/bin/chromium';
if (!existsSync(chromium_path)) {
  console.error(`${chromium_path} is missing: run scripts/setup.sh (it installs Debian's chromium)`);
  process.exit(1);
}
let playwright;
try {
  playwright = createRequire(join(here, 'package.json'))('playwright-core');
} catch (e) {
  console.error(`playwright-core is not installed in ${here}/node_modules: run scripts/setup.sh (${e.message})`);
  process.exit(1);
}

const profile = mkdtempSync(join(tmpdir(), 'filmstrip-chromium-'));
const browser = await playwright.chromium.launchPersistentContext(profile, {
  executablePath: chromium_path,
  headless: true,
  viewport: { width: 1280, height: 720 },
  args: [
    '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  ],
});
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
  await browser.close();
  rmSync(profile, { recursive: true, force: true });
}
process.exit(code);
