// The viewer page in headless Chromium: serves an exported tileset with
// `mktree serve`, loads the page, waits until no tile is loading, and
// checks that tiles were drawn: more than one tile loaded, no load error,
// a share of non-background pixels, and at least MIN_SHAPED internal tiles
// drawn as more than a box (their group bounds). Writes a screenshot.
//
// usage: node viewer/test.mjs MKTREE_BINARY TILES_DIR SCREENSHOT.png [MIN_COVERAGE [MIN_SHAPED]]
import { spawn } from 'node:child_process';
import { chromium } from 'playwright-core';

const [binary, tiles, shot, minCoverage = '0.05', minShaped = '0'] = process.argv.slice(2);
if (!binary || !tiles || !shot) {
  console.error('usage: node viewer/test.mjs MKTREE_BINARY TILES_DIR SCREENSHOT.png [MIN_COVERAGE [MIN_SHAPED]]');
  process.exit(2);
}

const server = spawn(binary, ['serve', tiles, '--port', '0'], { stdio: ['ignore', 'pipe', 'inherit'] });
const fail = (message) => {
  console.error(`viewer test: ${message}`);
  server.kill();
  process.exit(1);
};
const url = await new Promise((resolve, reject) => {
  let out = '';
  server.stdout.on('data', (chunk) => {
    out += chunk;
    const m = out.match(/at (http:\/\/127\.0\.0\.1:\d+\/)/);
    if (m) resolve(m[1]);
  });
  server.on('exit', (code) => reject(new Error(`mktree serve exited with ${code}`)));
}).catch((e) => fail(e.message));

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: [
    '--no-sandbox',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
    '--disable-quic',
    // WebGL without a GPU: ANGLE on SwiftShader.
    '--use-angle=swiftshader',
    '--enable-unsafe-swiftshader',
  ],
});
try {
  const page = await browser.newPage({ viewport: { width: 960, height: 600 } });
  const logs = [];
  page.on('console', (m) => logs.push(`${m.type()}: ${m.text()}`));
  page.on('pageerror', (e) => logs.push(`pageerror: ${e.message}`));
  page.on('response', (r) => {
    if (r.status() >= 400) logs.push(`${r.status()} ${r.url()}`);
  });
  page.on('requestfailed', (r) => logs.push(`failed ${r.url()}: ${r.failure()?.errorText}`));
  await page.goto(url);
  try {
    await page.waitForFunction(() => window.mktree && (window.mktree.ready || window.mktree.error), null, {
      timeout: 120_000,
    });
  } catch (e) {
    const state = await page.evaluate(() => JSON.stringify(window.mktree)).catch(() => 'unreadable');
    fail(`the page did not finish loading tiles: ${e.message}\nstate: ${state}\n${logs.join('\n')}`);
  }
  const state = await page.evaluate(() => ({
    error: window.mktree.error,
    tilesLoaded: window.mktree.tilesLoaded,
    triangles: window.mktree.triangles,
    shapedInternal: window.mktree.shapedInternal,
    coverage: window.mktree.coverage(),
  }));
  await page.screenshot({ path: shot });
  console.log(JSON.stringify({ url, screenshot: shot, ...state }));
  if (state.error) fail(`a tile failed to load: ${state.error}`);
  if (state.tilesLoaded < 2) fail(`only ${state.tilesLoaded} tiles loaded`);
  if (!(state.coverage >= Number(minCoverage))) {
    fail(`the picture is ${(100 * state.coverage).toFixed(2)}% drawn, under ${100 * Number(minCoverage)}%`);
  }
  if (state.shapedInternal < Number(minShaped)) {
    fail(`${state.shapedInternal} internal tiles drawn as more than a box, under ${minShaped}`);
  }
} finally {
  await browser.close();
  server.kill();
}
