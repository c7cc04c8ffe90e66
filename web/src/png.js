// An 8-bit PNG's pixels, read exactly: the browser's image decoders may premultiply alpha or
// convert colours, and an RGBM lightmap needs its bytes as written. Inflating is the browser's
// (DecompressionStream); what is left is PNG's row filters.

const SIGNATURE = [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a];
const CHANNELS = { 0: 1, 2: 3, 4: 2, 6: 4 };  // colour type -> samples per pixel

async function inflate(chunks) {
  const stream = new Blob(chunks).stream().pipeThrough(new DecompressionStream('deflate'));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

function paeth(a, b, c) {
  const p = a + b - c;
  const pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
  return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

/**
 * Decodes a non-interlaced 8-bit PNG (grey, grey + alpha, RGB or RGBA) to RGBA bytes, the top row
 * first. Returns {width, height, data: Uint8Array(width * height * 4)}; throws on other PNGs.
 */
export async function decodePng(bytes) {
  if (!SIGNATURE.every((v, i) => bytes[i] === v)) throw new Error('not a PNG file');
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  let header = null;
  const idat = [];
  for (let pos = 8; pos + 8 <= bytes.length;) {
    const length = view.getUint32(pos);
    const type = String.fromCharCode(...bytes.subarray(pos + 4, pos + 8));
    const body = bytes.subarray(pos + 8, pos + 8 + length);
    if (type === 'IHDR') {
      header = { width: view.getUint32(pos + 8), height: view.getUint32(pos + 12), depth: body[8],
                 colorType: body[9], interlace: body[12] };
    } else if (type === 'IDAT') {
      idat.push(body);
    } else if (type === 'IEND') {
      break;
    }
    pos += 12 + length;
  }
  if (!header) throw new Error('PNG without a header');
  const { width, height, depth, colorType, interlace } = header;
  const channels = CHANNELS[colorType];
  if (depth !== 8 || !channels || interlace !== 0) {
    throw new Error(`PNG of bit depth ${depth}, colour type ${colorType}, interlace ${interlace}: ` +
                    'only non-interlaced 8-bit grey, RGB and RGBA PNGs are read');
  }
  const raw = await inflate(idat);
  const stride = width * channels;
  if (raw.length < height * (stride + 1)) throw new Error('PNG data is truncated');
  const out = new Uint8Array(width * height * 4);
  let prev = new Uint8Array(stride);
  let row = new Uint8Array(stride);
  for (let y = 0; y < height; y++) {
    const start = y * (stride + 1);
    const filter = raw[start];
    const line = raw.subarray(start + 1, start + 1 + stride);
    for (let x = 0; x < stride; x++) {
      const a = x >= channels ? row[x - channels] : 0;
      const b = prev[x];
      const c = x >= channels ? prev[x - channels] : 0;
      let v = line[x];
      switch (filter) {
        case 0: break;
        case 1: v += a; break;
        case 2: v += b; break;
        case 3: v += (a + b) >> 1; break;
        case 4: v += paeth(a, b, c); break;
        default: throw new Error(`PNG row filter ${filter} is not defined`);
      }
      row[x] = v & 255;
    }
    for (let x = 0; x < width; x++) {
      const o = (y * width + x) * 4;
      const i = x * channels;
      if (channels >= 3) {
        out[o] = row[i]; out[o + 1] = row[i + 1]; out[o + 2] = row[i + 2];
      } else {
        out[o] = out[o + 1] = out[o + 2] = row[i];
      }
      out[o + 3] = channels === 4 ? row[i + 3] : channels === 2 ? row[i + 1] : 255;
    }
    [prev, row] = [row, prev];
  }
  return { width, height, data: out };
}
