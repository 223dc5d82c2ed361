// Copies the three.js runtime files from node_modules into vendor/three/ (committed), so
// the server ships the viewer with no CDN and a fresh clone needs no npm.
// Usage: cd clients/web && npm install && npm run vendor
import { copyFileSync, mkdirSync, readFileSync, writeFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const from = join(here, 'node_modules', 'three');
const to = join(here, 'vendor', 'three');
mkdirSync(to, { recursive: true });
for (const file of ['build/three.module.js', 'build/three.core.js', 'LICENSE']) {
  copyFileSync(join(from, file), join(to, file.split('/').pop()));
}
const version = JSON.parse(readFileSync(join(from, 'package.json'), 'utf8')).version;
writeFileSync(join(to, 'VERSION'), version + '\n');
console.log(`vendor/three updated to three ${version}`);
