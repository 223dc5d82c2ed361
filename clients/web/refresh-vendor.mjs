// Copies the runtime files of the viewer's npm dependencies from node_modules into vendor/
// (committed), so the server ships the viewer with no CDN and a fresh clone needs no npm:
//   vendor/three/        three.js core (three.module.js + three.core.js)
//   vendor/three/addons/ the three.js add-ons the viewer uses (GLTFLoader and what it imports,
//                        OrbitControls), at their paths under examples/jsm/
//   vendor/three-vrm/    @pixiv/three-vrm's ES module bundle (VRM avatars)
// Every module imports `three` by its bare name; index.html's import map points it at
// vendor/three/three.module.js.
// Usage: cd clients/web && npm install && npm run vendor
import { copyFileSync, mkdirSync, readFileSync, writeFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const modules = join(here, 'node_modules');
const versionOf = (pkg) => JSON.parse(readFileSync(join(modules, pkg, 'package.json'), 'utf8')).version;

function copy(pkg, file, to) {
  const target = join(here, 'vendor', to);
  mkdirSync(dirname(target), { recursive: true });
  copyFileSync(join(modules, pkg, file), target);
}

for (const file of ['build/three.module.js', 'build/three.core.js', 'LICENSE']) {
  copy('three', file, join('three', file.split('/').pop()));
}
for (const addon of ['loaders/GLTFLoader.js', 'utils/BufferGeometryUtils.js', 'utils/SkeletonUtils.js', 'controls/OrbitControls.js']) {
  copy('three', join('examples/jsm', addon), join('three/addons', addon));
}
writeFileSync(join(here, 'vendor/three/VERSION'), versionOf('three') + '\n');
copy('@pixiv/three-vrm', 'lib/three-vrm.module.min.js', 'three-vrm/three-vrm.module.min.js');
copy('@pixiv/three-vrm', 'LICENSE', 'three-vrm/LICENSE');
writeFileSync(join(here, 'vendor/three-vrm/VERSION'), versionOf('@pixiv/three-vrm') + '\n');
console.log(`vendor/ updated: three ${versionOf('three')}, @pixiv/three-vrm ${versionOf('@pixiv/three-vrm')}`);
