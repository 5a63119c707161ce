// Bundles three.js and its OrbitControls (ES modules) into one classic script,
// dist/three-bundle.js, that defines window.THREE: `sonar3d report` inlines it into the page, so
// the page needs no module loader, no import map and no network. Run by `npm ci` (postinstall)
// and `npm run build`.
import { build } from 'esbuild';
import { fileURLToPath } from 'node:url';
import path from 'node:path';

const here = path.dirname(fileURLToPath(import.meta.url));
await build({
  entryPoints: [path.join(here, 'src', 'three_entry.js')],
  bundle: true,
  minify: true,
  format: 'iife',
  target: ['es2020'],
  legalComments: 'eof',
  outfile: path.join(here, 'dist', 'three-bundle.js'),
  logLevel: 'warning',
});
console.log('sonar3d web: wrote dist/three-bundle.js');
