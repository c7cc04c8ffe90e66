// Bundles the viewer into dist/: index.html and viewer.js (three.js included).
import { build } from 'esbuild';
import { copyFile, mkdir } from 'node:fs/promises';

await mkdir('dist', { recursive: true });
await build({
  entryPoints: ['src/main.js'],
  bundle: true,
  format: 'esm',
  minify: true,
  sourcemap: true,
  target: 'es2020',
  outfile: 'dist/viewer.js',
  logLevel: 'warning',
});
await copyFile('src/index.html', 'dist/index.html');
