"""Writes an int8 copy (static, QDQ, per-channel weights) of a pruned BlazePose landmark model,
calibrated on person crops from real footage.

Usage: quantize_landmark_model.py FLOAT.onnx OUT.onnx VIDEO...

Calibration needs inputs like the ones the model sees in use: crops around a person, rotated
upright, 256x256, values v/255. A small tracker finds them with the float model itself (the
whole frame letterboxed to start, then each frame's crop from the previous frame's alignment
landmarks 33/34, as rigcast's tracker does), on frames decoded with the short side at 512 px
as `rigcast pose` decodes them. Every other frame of each video is used.

The result is not the float model: how far its landmarks move is measured and documented
(BENCHMARKS.md), and rigcast offers it only under its own name (`--model full-int8`).
"""
import json
import os
import subprocess
import sys

import numpy as np
import onnxruntime as ort
from onnxruntime.quantization import (CalibrationDataReader, QuantFormat, QuantType,
                                      quantize_static)
from onnxruntime.quantization.shape_inference import quant_pre_process

SIDE = 256
DECODE_SHORT_SIDE = 512
ROI_SCALE = 2.5  # MediaPipe's: twice the centre-to-scale distance, times 1.25
PRESENCE = 0.5


def frames(video):
    """RGB frames of `video`, short side scaled to DECODE_SHORT_SIDE."""
    probe = json.loads(subprocess.check_output(
        ["ffprobe", "-v", "error", "-select_streams", "v:0", "-show_entries",
         "stream=width,height", "-of", "json", video]))["streams"][0]
    w, h = probe["width"], probe["height"]
    k = DECODE_SHORT_SIDE / min(w, h)
    w, h = round(w * k / 2) * 2, round(h * k / 2) * 2
    ff = subprocess.Popen(["ffmpeg", "-nostdin", "-v", "error", "-i", video, "-vf",
                           f"scale={w}:{h}", "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
                          stdout=subprocess.PIPE)
    while True:
        buf = ff.stdout.read(w * h * 3)
        if len(buf) < w * h * 3:
            break
        yield np.frombuffer(buf, np.uint8).reshape(h, w, 3)
    ff.wait()


def crop(img, center, size, rotation):
    """Bilinear rotated square crop, black outside the frame, values v/255 (NHWC, batch 1)."""
    h, w, _ = img.shape
    s, c = np.sin(rotation), np.cos(rotation)
    n = (np.arange(SIDE) + 0.5) / SIDE - 0.5
    u, v = np.meshgrid(n * size, n * size)
    x = center[0] + c * u - s * v - 0.5
    y = center[1] + s * u + c * v - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    padded = np.zeros((h + 2, w + 2, 3), np.float32)
    padded[1:-1, 1:-1] = img

    def at(yy, xx):
        return padded[np.clip(yy + 1, 0, h + 1), np.clip(xx + 1, 0, w + 1)]
    top = at(y0, x0) * (1 - fx) + at(y0, x0 + 1) * fx
    bot = at(y0 + 1, x0) * (1 - fx) + at(y0 + 1, x0 + 1) * fx
    return ((top * (1 - fy) + bot * fy) / 255.0)[None].astype(np.float32)


def to_frame(p, center, size, rotation):
    s, c = np.sin(rotation), np.cos(rotation)
    n = (p / SIDE - 0.5) * size
    return center + np.array([c * n[0] - s * n[1], s * n[0] + c * n[1]])


def person_crops(session, video):
    """The model inputs a tracker would give on every other frame of `video`."""
    roi = None
    for i, img in enumerate(frames(video)):
        h, w, _ = img.shape
        if roi is None:
            roi = (np.array([w / 2, h / 2]), float(max(w, h)), 0.0)
        x = crop(img, *roi)
        lm, presence = session.run(["Identity", "Identity_1"], {"input_1": x})
        if i % 2 == 0:
            yield x
        if presence.ravel()[0] < PRESENCE:
            roi = None
            continue
        lm = lm.reshape(-1, 5)
        center = to_frame(lm[33, :2], *roi)
        d = to_frame(lm[34, :2], *roi) - center
        roi = (center, ROI_SCALE * float(np.hypot(*d)), float(np.arctan2(d[0], -d[1])))


class Crops(CalibrationDataReader):
    def __init__(self, inputs):
        self.inputs = iter(inputs)

    def get_next(self):
        x = next(self.inputs, None)
        return None if x is None else {"input_1": x}


def main():
    src, dst, videos = sys.argv[1], sys.argv[2], sys.argv[3:]
    options = ort.SessionOptions()
    options.intra_op_num_threads = 2
    session = ort.InferenceSession(src, options, providers=["CPUExecutionProvider"])
    inputs = [x for v in videos for x in person_crops(session, v)]
    print(f"{src}: {len(inputs)} calibration crops from {len(videos)} videos")
    prepared = dst + ".pre.onnx"
    quant_pre_process(src, prepared, skip_symbolic_shape=True)
    quantize_static(prepared, dst, Crops(inputs), quant_format=QuantFormat.QDQ,
                    activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8,
                    per_channel=True)
    os.remove(prepared)


if __name__ == "__main__":
    main()
