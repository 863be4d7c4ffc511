// Opens the benchmark's pages in headless Chromium (Debian's /usr/bin/chromium, driven by
// puppeteer-core) and checks the DOM after the scripts ran. Run by the ctest test
// benchmark/pages_browser_test, which starts a server with one dataset ("tiny") and two scored
// submissions ("exact": renders equal to the photos, "noisy") and passes its base URL:
//   node benchmark_pages.mjs http://127.0.0.1:PORT
// Checks: the dataset list links the dataset; the dataset page links its downloads; the
// leaderboard lists both submissions best first, draws a boxplot per submission and re-sorts
// when a header is clicked; the submission page shows its per-image table and error images;
// every same-origin link and image on these pages loads (HTTP 200, images decoded); no console
// error or uncaught exception; the leaderboard has its rows with JavaScript disabled too.
// Exit code 0 when every check passed, 1 otherwise (each failure printed on one line).
import puppeteer from 'puppeteer-core';

const base = process.argv[2];
const chromium = process.env.CHROMIUM || '/usr/bin/chromium';
const failures = [];
const check = (condition, message) => {
  if (!condition) failures.push(message);
};

const browser = await puppeteer.launch({
  executablePath: chromium,
  headless: true,
  args: ['--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-extensions'],
});
try {
  const page = await browser.newPage();
  page.on('console', (message) => {
    if (message.type() === 'error') failures.push(`console error on ${page.url()}: ${message.text()}`);
  });
  page.on('pageerror', (error) => failures.push(`uncaught exception on ${page.url()}: ${error}`));

  // Every same-origin link of the current page answers 200; every image decoded.
  const checkLinksAndImages = async () => {
    const { links, images } = await page.evaluate(() => ({
      links: Array.from(document.querySelectorAll('a[href]'), (a) => a.href)
        .filter((href) => href.startsWith(location.origin)),
      images: Array.from(document.images, (img) => ({
        src: img.src, ok: img.complete && img.naturalWidth > 0 })),
    }));
    for (const href of links) {
      const status = await page.evaluate(async (url) => (await fetch(url)).status, href);
      check(status === 200, `broken link ${href} (HTTP ${status}) on ${page.url()}`);
    }
    for (const image of images) check(image.ok, `broken image ${image.src} on ${page.url()}`);
    return { links, images };
  };
  const open = async (path) => {
    const response = await page.goto(base + path, { waitUntil: 'networkidle0' });
    check(response.status() === 200, `${path}: HTTP ${response.status()}`);
  };

  await open('/');
  check(await page.$('table#datasets a[href="/datasets/tiny"]'), 'dataset list: no link to tiny');
  await checkLinksAndImages();

  await open('/datasets/tiny');
  const downloads = await page.$$eval('ul.downloads a', (as) => as.map((a) => a.textContent));
  check(JSON.stringify(downloads) === JSON.stringify(['test-cameras.tar', 'training.tar']),
        `dataset page downloads: ${JSON.stringify(downloads)}`);
  check((await page.$$('table#test-images tbody tr')).length === 2, 'dataset page: not 2 test images');
  check((await page.content()).includes('curl'), 'dataset page: no curl example');
  await checkLinksAndImages();

  await open('/datasets/tiny/leaderboard');
  const methods = () => page.$$eval('table#leaderboard tbody tr td:nth-child(2)',
                                    (tds) => tds.map((td) => td.textContent));
  check(JSON.stringify(await methods()) === '["exact","noisy"]',
        `leaderboard order: ${JSON.stringify(await methods())}`);
  check((await page.$$('svg g.box')).length === 2, 'leaderboard: not one boxplot per submission');
  // Click "1-ncc mean" (4th column): ascending, then descending.
  const header = await page.$('table#leaderboard th:nth-child(4)');
  await header.click();
  check(JSON.stringify(await methods()) === '["exact","noisy"]', 'sort ascending failed');
  await header.click();
  check(JSON.stringify(await methods()) === '["noisy","exact"]',
        `sort descending: ${JSON.stringify(await methods())}`);
  const { links } = await checkLinksAndImages();
  const submissionLinks = links.filter((href) => href.includes('/submissions/'));
  check(submissionLinks.length === 2, `leaderboard: ${submissionLinks.length} submission links`);

  for (const href of submissionLinks) {
    await open(href.slice(base.length));
    check((await page.$eval('#status', (b) => b.textContent)) === 'done', `${href}: not done`);
    check((await page.$$('table#images tbody tr')).length === 2, `${href}: not 2 image rows`);
    const { images } = await checkLinksAndImages();
    check(images.length === 2, `${href}: ${images.length} error images`);
  }

  // Without JavaScript the server-rendered rows are all there.
  await page.setJavaScriptEnabled(false);
  await open('/datasets/tiny/leaderboard');
  check((await page.$$('table#leaderboard tbody tr')).length === 2, 'no rows without JavaScript');
} finally {
  await browser.close();
}
for (const failure of failures) console.log(`FAIL ${failure}`);
console.log(failures.length ? `${failures.length} check(s) failed` : 'all checks passed');
process.exit(failures.length ? 1 : 0);
