// Headless Chromium for the replay page's tools (the filmstrip, crates/scenes/web/filmstrip.mjs) and
// its browser test (tests/browser/replay_check.mjs): Debian's /usr/bin/chromium (or $CHROMIUM)
// driven by playwright-core from this folder's node_modules, both installed by
// scripts/setup.sh, in a fresh empty profile. `open()` returns { browser, close }; on a missing
// piece it prints what to install and exits 1.

import { createRequire } from 'node:module';
import { existsSync, mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));

export async function open() {
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
  const profile = mkdtempSync(join(tmpdir(), 'replay-chromium-'));
  // Without the background-networking flags Chromium stalls on a closed network.
  const browser = await playwright.chromium.launchPersistentContext(profile, {
    executablePath: chromium_path,
    headless: true,
    viewport: { width: 1280, height: 720 },
    args: [
      '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
      '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    ],
  });
  const close = async () => {
    await browser.close();
    rmSync(profile, { recursive: true, force: true });
  };
  return { browser, close };
}
