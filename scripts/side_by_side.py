#!/usr/bin/python3
"""Side by side: A.pfm | B.pfm | 4 x |A - B| as one sRGB PNG; prints the PSNR of B against A.
   scripts/side_by_side.py A.pfm B.pfm OUT.png   (numpy only)"""
import struct
import sys
import zlib

import numpy as np


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    return data.reshape(h, w, 3 if kind == b"PF" else 1)[::-1]


def write_png(path, rgb):
    x = np.clip(rgb, 0, 1)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    u8 = (x * 255 + 0.5).astype(np.uint8)
    h, w, _ = u8.shape
    raw = b"".join(b"\0" + u8[y].tobytes() for y in range(h))

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


a, b = read_pfm(sys.argv[1]), read_pfm(sys.argv[2])
err = np.repeat(np.abs(a - b).mean(axis=2, keepdims=True) * 4, 3, axis=2)
gap = np.ones((a.shape[0], 4, 3), dtype=np.float32)
write_png(sys.argv[3], np.concatenate([a, gap, b, gap, err], axis=1))
print(f"PSNR {-10 * np.log10(((a - b) ** 2).mean()):.2f} dB")
