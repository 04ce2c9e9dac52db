// Starts Debian's Chromium headless through playwright-core, shared by render.mjs and the viewer's end-to-end test.
// Playwright gives it a fresh, empty profile (--user-data-dir) of its own; never `npx playwright install`.
import fs from 'node:fs';
import path from 'node:path';

/// The Chromium to use: $MGCLOTH_CHROMIUM, else chromium or chromium-browser on PATH; null when none.
export function findChromium() {
  const env = process.env.MGCLOTH_CHROMIUM;
  if (env) return fs.existsSync(env) ? env : null;
  for (const dir of (process.env.PATH || '/usr/bin').split(':')) {
    for (const name of ['chromium', 'chromium-browser']) {
      const p = path.join(dir || '.', name);
      try {
        fs.accessSync(p, fs.constants.X_OK);
        return p;
      } catch {}
    }
  }
  return null;
}

// Without the networking flags Chromium keeps trying Google's hosts, which a closed network refuses; WebGL comes
// from SwiftShader, the CPU rasterizer, since headless machines have no GPU.
export const CHROMIUM_ARGS = [
  '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
  '--disable-component-update', '--disable-sync', '--enable-unsafe-swiftshader', '--use-angle=swiftshader',
];

export async function launch(executablePath) {
  const { chromium } = await import('playwright-core');
  return chromium.launch({ executablePath, headless: true, args: CHROMIUM_ARGS });
}

/// Makes `page` refuse every request that does not go to the loopback server, and records them in `refused`:
/// the viewer must work with no network at all.
export async function localOnly(page, refused = []) {
  await page.route('**/*', (route) => {
    const url = new URL(route.request().url());
    if (url.hostname === '127.0.0.1' || url.protocol === 'data:' || url.protocol === 'blob:') return route.continue();
    refused.push(url.href);
    return route.abort();
  });
  return refused;
}
