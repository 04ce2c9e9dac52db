#!/usr/bin/env node
// Driven by `mgcloth render`: opens the viewer page (already served by mgcloth on 127.0.0.1) in headless Chromium
// at the requested size, waits until the page says the frame is drawn, and saves a screenshot.
//   node render.mjs --url URL --out PNG --width W --height H --chromium PATH [--timeout S]
// Exit 0 with one line "wrote PNG ..." on success; otherwise non-zero with the reason as the last line.
import fs from 'node:fs';
import path from 'node:path';
import { launch, localOnly } from './chromium.mjs';

function args() {
  const a = {};
  const argv = process.argv.slice(2);
  for (let i = 0; i < argv.length; i += 2) {
    if (!argv[i].startsWith('--') || i + 1 >= argv.length) throw new Error(`bad argument ${argv[i]}`);
    a[argv[i].slice(2)] = argv[i + 1];
  }
  for (const k of ['url', 'out', 'chromium']) if (!a[k]) throw new Error(`--${k} is required`);
  return { url: a.url, out: a.out, chromium: a.chromium, width: parseInt(a.width || '960', 10),
           height: parseInt(a.height || '600', 10), timeout: 1000 * parseFloat(a.timeout || '120') };
}

async function main() {
  const o = args();
  const browser = await launch(o.chromium);
  try {
    const page = await browser.newPage({ viewport: { width: o.width, height: o.height }, deviceScaleFactor: 1 });
    const refused = await localOnly(page);
    const logs = [];
    page.on('console', (m) => { if (m.type() === 'error') logs.push(m.text()); });
    page.on('pageerror', (e) => logs.push(String(e)));
    await page.goto(o.url, { timeout: o.timeout });
    await page.waitForFunction(() => document.body.dataset.ready === '1' || document.body.dataset.error,
                               null, { timeout: o.timeout, polling: 100 });
    const error = await page.evaluate(() => document.body.dataset.error);
    if (error) throw new Error(error);
    if (refused.length) throw new Error(`the page asked for outside addresses: ${refused.join(', ')}`);
    const caption = await page.evaluate(() => document.body.dataset.caption);
    // Written beside the target and renamed over it, so a reader never sees half a picture.
    const tmp = path.join(path.dirname(o.out), `.${path.basename(o.out)}.${process.pid}.tmp.png`);
    await page.screenshot({ path: tmp, type: 'png' });
    fs.renameSync(tmp, o.out);
    console.log(`wrote ${o.out} (${o.width}x${o.height}): ${caption}`);
    if (logs.length) console.error(`page errors: ${logs.join('; ')}`);
  } finally {
    await browser.close();
  }
}

main().catch((e) => {
  console.error(`render: ${e.message?.split('\n')[0] || e}`);
  process.exit(1);
});
