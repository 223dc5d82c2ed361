"""MediaPipe Pose (Python) on the frames ffmpeg decodes from a video: the baseline that
scripts/bench-vision.sh compares `rigcast pose` with.

Usage: bench_mediapipe.py VIDEO lite|full [PEOPLE] [--max-frames N] [--landmarks OUT.json]
Prints one line: `mediapipe MODEL VIDEO people=P frames=N with_person=N found=N0,N1,...,NP
fps_with_decoding=X fps_model_only=Y cpu_ms_per_frame=C decoder_cpu_ms_per_frame=D` (`found`: the
timed frames by how many people were found in them, 0 to P; `C`: CPU time a timed frame, this
process's after the warm-up frame plus the whole of ffmpeg's, which is `D`: on a shared machine
the CPU a frame is what the load does not swing as it swings the frame rate). `--max-frames` stops after N frames (the warm-up frame included);
`--landmarks` (one person only) writes `{"width", "height", "frames": [...], "world": [...]}`
with, per frame (the warm-up frame included), `null` or the 33 landmarks: in `frames` as
`[x, y, visibility]` in pixels, in `world` as `[x, y, z]` in metres (MediaPipe's world
landmarks: hip-centred, x right and y down in the picture, z away from the camera). The
independent reference the vision tests judge coverage, left/right labels and 3D against. Frames come from an ffmpeg pipe as RGB at the video's own size (what MediaPipe
is given in its own examples); decoding time is counted in the first figure and left out of the
second.

PEOPLE 1 (the default) runs `solutions.pose`, MediaPipe's single-person tracker. PEOPLE 2 or more
runs the Tasks API's `PoseLandmarker` in video mode with `num_poses=PEOPLE`, MediaPipe's own way
to follow several people; `with_person` then counts frames where all of them were found. Its
model bundle is not in the wheel (MediaPipe downloads it), so it is built from the same two
models the wheel ships for `solutions.pose` (the detector and the landmark model), given the
input normalisation `solutions.pose` applies to them ([-1, 1] and [0, 1]), and cached next to
the wheel (written whole under another name first: two runs may build it at once). Its landmarks
match `solutions.pose`'s within 1-2.5 px a point (mean) on a person alone, asked for one.
"""
import json
import os
import resource
import subprocess
import sys
import time

import mediapipe as mp
import numpy as np


def landmark_model(model):
    return os.path.join(os.path.dirname(mp.__file__), "modules", "pose_landmark",
                        f"pose_landmark_{model}.tflite")


def with_image_metadata(path, mean, std):
    """The model with metadata saying how its float input is normalised (the Tasks API
    refuses a float image input without it); every output is a plain feature tensor."""
    from mediapipe.tasks.python.metadata.metadata_writers import metadata_writer, writer_utils
    buf = bytearray(open(path, "rb").read())
    writer = metadata_writer.MetadataWriter.create(buf).add_general_info(os.path.basename(path), "")
    writer.add_image_input(norm_mean=[mean], norm_std=[std])
    for _ in range(writer_utils.get_subgraph(buf).OutputsLength()):
        writer.add_feature_output()
    return writer.populate()[0]


def task_bundle(model):
    from mediapipe.tasks.python.metadata.metadata_writers import model_asset_bundle_utils
    bundle = os.path.join(os.path.dirname(mp.__file__), f"rigcast_pose_landmarker_{model}.task")
    if not os.path.exists(bundle):
        detector = os.path.join(os.path.dirname(mp.__file__), "modules", "pose_detection",
                                "pose_detection.tflite")
        model_asset_bundle_utils.create_model_asset_bundle({
            "pose_detector.tflite": with_image_metadata(detector, 127.5, 127.5),
            "pose_landmarks_detector.tflite": with_image_metadata(landmark_model(model), 0.0, 255.0),
        }, f"{bundle}.{os.getpid()}")
        os.replace(f"{bundle}.{os.getpid()}", bundle)
    return bundle


def tracker(model, people):
    """A function from (RGB frame, frame index) to the number of people found."""
    if people == 1:
        pose = mp.solutions.pose.Pose(static_image_mode=False,
                                      model_complexity={"lite": 0, "full": 1}[model])
        def one(img, _):
            result = pose.process(img)
            found, world = result.pose_landmarks, result.pose_world_landmarks
            h, w = img.shape[:2]
            return (int(found is not None),
                    found and ([[p.x * w, p.y * h, p.visibility] for p in found.landmark],
                               world and [[p.x, p.y, p.z] for p in world.landmark]))
        return one
    from mediapipe.tasks import python as tasks
    from mediapipe.tasks.python import vision
    landmarker = vision.PoseLandmarker.create_from_options(vision.PoseLandmarkerOptions(
        base_options=tasks.BaseOptions(model_asset_path=task_bundle(model)),
        running_mode=vision.RunningMode.VIDEO, num_poses=people))
    # Video mode wants increasing timestamps; their spacing does not change the work done.
    return lambda img, i: (len(landmarker.detect_for_video(
        mp.Image(image_format=mp.ImageFormat.SRGB, data=img), i * 33).pose_landmarks), None)


def option(name, default=None):
    if name in sys.argv:
        at = sys.argv.index(name)
        value = sys.argv[at + 1]
        del sys.argv[at:at + 2]
        return value
    return default


max_frames = int(option("--max-frames", 0)) or None
landmarks_out = option("--landmarks")
video, model = sys.argv[1], sys.argv[2]
people = int(sys.argv[3]) if len(sys.argv) > 3 else 1
if landmarks_out and people != 1:
    sys.exit("--landmarks needs PEOPLE 1")
probe = json.loads(subprocess.check_output(
    ["ffprobe", "-v", "error", "-select_streams", "v:0", "-show_entries",
     "stream=width,height", "-of", "json", video]))["streams"][0]
w, h = probe["width"], probe["height"]
track = tracker(model, people)
# First frame outside the timing: MediaPipe builds its graph lazily.
# The decoder's CPU (ffprobe's left out) is read from the children's usage once it is waited for.
children_before = resource.getrusage(resource.RUSAGE_CHILDREN)
ff = subprocess.Popen(["ffmpeg", "-nostdin", "-v", "error", "-i", video, "-f", "rawvideo",
                       "-pix_fmt", "rgb24", "-"], stdout=subprocess.PIPE)
frame_bytes = w * h * 3
index = frames = found = 0
by_count = [0] * (people + 1)
model_secs = 0.0
start = None
per_frame = []
while max_frames is None or index < max_frames:
    buf = ff.stdout.read(frame_bytes)
    if len(buf) < frame_bytes:
        break
    img = np.frombuffer(buf, np.uint8).reshape(h, w, 3)
    t = time.perf_counter()
    n, points = track(img, index)
    per_frame.append(points)
    index += 1
    if start is None:
        start = time.perf_counter()  # the clock starts after the first (warm-up) frame
        cpu_start = time.process_time()
        continue
    model_secs += time.perf_counter() - t
    frames += 1
    found += n >= people
    by_count[min(n, people)] += 1
total = time.perf_counter() - start
cpu = time.process_time() - cpu_start
ff.kill()
ff.wait()
children = resource.getrusage(resource.RUSAGE_CHILDREN)
decoder_cpu = (children.ru_utime - children_before.ru_utime
               + children.ru_stime - children_before.ru_stime)
if landmarks_out:
    with open(landmarks_out, "w") as out:
        json.dump({"width": w, "height": h, "frames": [p and p[0] for p in per_frame],
                   "world": [p and p[1] for p in per_frame]}, out)
print(f"mediapipe {model} {video} people={people} frames={frames} with_person={found} "
      f"found={','.join(map(str, by_count))} fps_with_decoding={frames / total:.1f} fps_model_only={frames / model_secs:.1f} "
      f"cpu_ms_per_frame={1e3 * (cpu + decoder_cpu) / max(frames, 1):.2f} "
      f"decoder_cpu_ms_per_frame={1e3 * decoder_cpu / max(frames, 1):.2f}")
