// Opens a replay page in headless Chromium and checks it works:
//   node tests/browser/replay_check.mjs PAGE.html SCREENSHOT.png [FRAME TEXT]...
// - the page loads with no console error and no page error;
// - the canvas is drawn (the screenshot of the 3-D view has many distinct colours);
// - playback advances (window.__replay.frame moves on while playing);
// - for each FRAME TEXT pair, the overlay shows TEXT once the slider is moved to FRAME.
// - the timeline: slider and skill strip aligned, every legend entry shown, a fall in red, each
//   foot's floor contact in its gait lane.
// Opens Chromium through crates/scenes/web/chromium.mjs. Prints one JSON line of measurements; exits 1
// with the reason on failure.

import { resolve } from 'node:path';
import { pathToFileURL } from 'node:url';
import { open } from '../../crates/scenes/web/chromium.mjs';

const [page_path, shot_path, ...expect] = process.argv.slice(2);
if (!page_path || !shot_path || expect.length % 2) {
  console.error('usage: node replay_check.mjs PAGE.html SCREENSHOT.png [FRAME TEXT]...');
  process.exit(2);
}
const { browser, close } = await open();
const problems = [];
let result = {};
try {
  const page = browser.pages()[0] || (await browser.newPage());
  page.on('console', (m) => { if (m.type() === 'error') problems.push(`console error: ${m.text()}`); });
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  await page.goto(pathToFileURL(resolve(page_path)).href);
  await page.waitForFunction(() => window.__replay && window.__replay.ready && window.__replay.drawn > 2, null,
    { timeout: 60_000 });
  const first = await page.evaluate(() => ({ ...window.__replay }));
  // Sample the playback for 1.5 s: any frame other than the first seen means it advanced (a
  // short recording stops on its last frame).
  const seen = new Set([first.frame]);
  let later = first;
  for (let i = 0; i < 15; i++) {
    await page.waitForTimeout(100);
    later = await page.evaluate(() => ({ ...window.__replay }));
    seen.add(later.frame);
  }
  const shot = await page.screenshot({ path: shot_path });
  // Count distinct colours in the 3-D view (the canvas) by reading it back in the page.
  const colours = await page.evaluate(() => {
    const src = document.querySelector('#view canvas');
    const c = document.createElement('canvas');
    c.width = 256; c.height = 144;
    const ctx = c.getContext('2d');
    ctx.drawImage(src, 0, 0, c.width, c.height);
    const px = ctx.getImageData(0, 0, c.width, c.height).data;
    const seen = new Set();
    for (let i = 0; i < px.length; i += 4) seen.add((px[i] << 16) | (px[i + 1] << 8) | px[i + 2]);
    return seen.size;
  });
  result = { frames: first.frames, first_frame: first.frame, later_frame: later.frame, frames_seen: seen.size, drawn: later.drawn,
    playing: later.playing, colours, screenshot_bytes: shot.length };
  if (colours < 50) problems.push(`the canvas looks blank: ${colours} distinct colours`);
  if (!(seen.size > 1 && later.drawn > first.drawn)) {
    problems.push(`playback did not advance: frames seen ${[...seen].join(', ')}, draws ${first.drawn} → ${later.drawn}`);
  }
  // An episode plays once and stops on its last frame; before that it must be playing.
  if (!later.playing && later.frame !== later.frames - 1) problems.push('the page is not playing');
  // The timeline: the slider and the skill strip span the same width, and their playheads agree
  // at the start, the middle and the end; the legend shows every skill (no row cut off); a
  // recording with a fall shows the fall's red on the strip.
  result.layout = await page.evaluate(async () => {
    const box = (id) => document.getElementById(id).getBoundingClientRect();
    const out = { scrub: box('scrub'), strip: box('strip'), playheads: [] };
    const hook = window.__replay;
    const strip = document.getElementById('strip');
    for (const f of [0, Math.floor((hook.frames - 1) / 2), hook.frames - 1]) {
      const s = document.getElementById('scrub');
      s.value = String(f);
      s.dispatchEvent(new Event('input'));
      await new Promise((r) => setTimeout(r, 150));
      // The slider's thumb centre, from its value as the browser lays it out (an 8 px inset).
      const r = s.getBoundingClientRect();
      const thumb = r.left + 8 + (f / Math.max(1, hook.frames - 1)) * (r.width - 16);
      // The strip's playhead: its white column, read back from the canvas.
      const ctx = strip.getContext('2d');
      const row = ctx.getImageData(0, 2, strip.width, 1).data;
      let x = -1;
      for (let i = 0; i < strip.width; i++) if (row[4 * i] === 255 && row[4 * i + 1] === 255 && row[4 * i + 2] === 255) { x = i; break; }
      out.playheads.push({ frame: f, thumb, strip: x < 0 ? null : strip.getBoundingClientRect().left + x + 1 });
    }
    const legend = document.getElementById('legend');
    const lb = legend.getBoundingClientRect();
    const items = [...legend.querySelectorAll('span')];
    out.legend = { items: items.length, cut: items.filter((e) => e.getBoundingClientRect().bottom > lb.bottom + 0.5).length };
    const px = strip.getContext('2d').getImageData(0, 0, strip.width, strip.height).data;
    let red = 0;
    for (let i = 0; i < px.length; i += 4) if (px[i] === 255 && px[i + 1] === 32 && px[i + 2] === 32) red++;
    out.fall_frames = hook.fall_frames;
    out.red_pixels = red;
    // The gait lanes: the left foot's floor contact at rows 1–2 of the strip, the right's at 4–5.
    out.foot_frames = hook.foot_frames;
    out.foot_lane_pixels = [1, 4].map((y) => {
      const row = strip.getContext('2d').getImageData(0, y, strip.width, 1).data;
      let n = 0;
      for (let i = 0; i < row.length; i += 4) if (row[i] === 244 && row[i + 1] === 244 && row[i + 2] === 244) n++;
      return n;
    });
    return out;
  });
  const L = result.layout;
  if (Math.abs(L.scrub.left - L.strip.left) > 1 || Math.abs(L.scrub.right - L.strip.right) > 1) {
    problems.push(`the slider (${L.scrub.left}–${L.scrub.right}) and the strip (${L.strip.left}–${L.strip.right}) differ in width`);
  }
  for (const p of L.playheads) {
    if (p.strip === null || Math.abs(p.strip - p.thumb) > 2) {
      problems.push(`frame ${p.frame}: the strip's playhead at ${p.strip}, the slider's at ${p.thumb.toFixed(1)}`);
    }
  }
  if (L.legend.cut > 0) problems.push(`${L.legend.cut} of ${L.legend.items} legend entries are cut off`);
  if (L.fall_frames > 0 && L.red_pixels === 0) problems.push('a fall is recorded and the strip shows no red');
  if (L.foot_frames) {
    [0, 1].forEach((s) => {
      if (L.foot_frames[s] > 0 && L.foot_lane_pixels[s] === 0) {
        problems.push(`the ${s ? 'right' : 'left'} foot touches the floor in ${L.foot_frames[s]} frames and its gait lane is empty`);
      }
    });
  }
  // The overlay at given frames: the slider moved there as a user would.
  result.overlay = {};
  for (let i = 0; i < expect.length; i += 2) {
    const [frame, text] = [Number(expect[i]), expect[i + 1]];
    await page.evaluate((f) => {
      const s = document.getElementById('scrub');
      s.value = String(f);
      s.dispatchEvent(new Event('input'));
    }, frame);
    await page.waitForTimeout(300);
    const info = await page.evaluate(() => document.getElementById('info').textContent);
    result.overlay[frame] = info;
    if (!info.includes(text)) problems.push(`frame ${frame}: the overlay reads "${info}", without "${text}"`);
  }
} catch (e) {
  problems.push(`${e.message}`);
} finally {
  await close();
}
console.log(JSON.stringify(result));
if (problems.length) {
  console.error(problems.join('\n'));
  process.exit(1);
}
