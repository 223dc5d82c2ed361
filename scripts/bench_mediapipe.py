"""MediaPipe Pose (Python) on the frames ffmpeg decodes from a video: the baseline that
scripts/bench-vision.sh compares `rigcast pose` with.

Usage: bench_mediapipe.py VIDEO lite|full
Prints one line: `mediapipe MODEL VIDEO frames=N with_person=N fps_with_decoding=X fps_model_only=Y`.
Frames come from an ffmpeg pipe as RGB at the video's own size (what MediaPipe is given in its
own examples); decoding time is counted in the first figure and left out of the second.
"""
import json
import subprocess
import sys
import time

import mediapipe as mp
import numpy as np

video, model = sys.argv[1], sys.argv[2]
probe = json.loads(subprocess.check_output(
    ["ffprobe", "-v", "error", "-select_streams", "v:0", "-show_entries",
     "stream=width,height", "-of", "json", video]))["streams"][0]
w, h = probe["width"], probe["height"]
pose = mp.solutions.pose.Pose(static_image_mode=False, model_complexity={"lite": 0, "full": 1}[model])
# First frame outside the timing: MediaPipe builds its graph lazily.
ff = subprocess.Popen(["ffmpeg", "-nostdin", "-v", "error", "-i", video, "-f", "rawvideo",
                       "-pix_fmt", "rgb24", "-"], stdout=subprocess.PIPE)
frame_bytes = w * h * 3
frames = found = 0
model_secs = 0.0
start = None
while True:
    buf = ff.stdout.read(frame_bytes)
    if len(buf) < frame_bytes:
        break
    img = np.frombuffer(buf, np.uint8).reshape(h, w, 3)
    t = time.perf_counter()
    result = pose.process(img)
    if start is None:
        start = time.perf_counter()  # the clock starts after the first (warm-up) frame
        continue
    model_secs += time.perf_counter() - t
    frames += 1
    found += result.pose_landmarks is not None
total = time.perf_counter() - start
ff.wait()
print(f"mediapipe {model} {video} frames={frames} with_person={found} "
      f"fps_with_decoding={frames / total:.1f} fps_model_only={frames / model_secs:.1f}")
