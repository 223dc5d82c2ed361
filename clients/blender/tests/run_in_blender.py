"""End-to-end check of the add-on inside real Blender, driven by tests/tests/blender_client.rs.

    blender -b --factory-startup --python-exit-code 1 \
        --python clients/blender/tests/run_in_blender.py -- ARGS
    python run_in_blender.py -- ARGS          (a venv holding the `bpy` wheel: module mode)

    ARGS: (--zip dist/rigcast_livelink.zip | --build-zip OUT.zip) --address 127.0.0.1:8717
          --out obs.json [--mode stream|mapping|connect] [--seconds 2] [--install legacy|extension]

Every mode installs the add-on from the zip with default preferences (`legacy`: the add-on
route, every version; `extension`: the 4.2+ extensions platform), enables it and connects. The
source tree is never on sys.path: the code that runs is the installed copy, and the script
reports where it was loaded from so the caller can check.
- stream (default): creates an armature per subject with the add-on's operator, applies the
  stream for --seconds while recording, then writes what it observed (per applied frame: seq,
  capture time, bone head positions; the recorded Action's curves). The Rust side judges the
  numbers against forward kinematics.
- mapping: creates armatures for the first target subject and its source, writes the add-on's
  mapping list and bone colours (gradient, random), then picks a row and a bone in the list,
  sends the override and writes the list again once the server's new mapping has arrived. The
  Rust side compares both lists with the `mapping` messages its own client received.
- connect: only checks that the panel is registered, records the default settings, and waits
  for the hello, the skeletons and applied frames.

Background Blender and the `bpy` module run no event loop, so timers never fire there; this
script calls the add-on's timer function itself, at 60 Hz.
"""

import importlib.util
import json
import os
import sys
import time
import traceback

import bpy
from mathutils import Vector


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    args = {"seconds": "2.0", "warmup": "0.5", "mode": "stream"}
    key = None
    for token in argv:
        if token.startswith("--"):
            key = token[2:]
            args[key] = "1"
        elif key:
            args[key] = token
            key = None
    return args


def find_addon_module(part="livelink"):
    for name, module in list(sys.modules.items()):
        if name.endswith("rigcast_livelink." + part):
            return module
    raise RuntimeError("add-on module rigcast_livelink.%s not loaded" % part)


CLIENT_DIR = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))


def build_zip(out_path):
    """Builds the zip with the documented builder, loaded by file path so that its folder (the
    add-on's source tree) never lands on sys.path."""
    spec = importlib.util.spec_from_file_location("rigcast_build_zip", os.path.join(CLIENT_DIR, "build_zip.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.build(out_path)


def install_addon(zip_path, how):
    if how == "extension":
        # Blender 4.2+: the extensions platform validates the manifest and installs into the
        # user repository; the module is then bl_ext.user_default.rigcast_livelink.
        result = bpy.ops.extensions.package_install_files(
            filepath=zip_path, repo="user_default", enable_on_install=True
        )
        if "FINISHED" not in result:
            raise RuntimeError("package_install_files returned %s" % result)
    else:
        bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
        result = bpy.ops.preferences.addon_enable(module="rigcast_livelink")
        if "FINISHED" not in result:
            raise RuntimeError("addon_enable returned %s" % result)
    if not hasattr(bpy.types.Scene, "rigcast"):
        raise RuntimeError("add-on enabled but Scene.rigcast is not registered")
    if not hasattr(bpy.types, "RIGCAST_PT_panel"):
        raise RuntimeError("add-on enabled but its panel is not registered")


def main():
    args = parse_args()
    out = {"ok": False, "blender_version": bpy.app.version_string}
    try:
        run(args, out)
        out["ok"] = True
    except Exception:
        out["error"] = traceback.format_exc()
        print(out["error"], file=sys.stderr)
    with open(args["out"], "w") as handle:
        json.dump(out, handle)
    if os.path.basename(sys.argv[0]) == os.path.basename(__file__):
        # Module mode (python run_in_blender.py): the bpy 4.2 wheel segfaults while the
        # interpreter tears the module down, after all the work is done; leave without it.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0 if out["ok"] else 1)
    if not out["ok"]:
        sys.exit(1)


def run(args, out):
    if "build-zip" in args:
        # Build with the documented builder, under this Python (no system python needed).
        build_zip(args["build-zip"])
        args["zip"] = args["build-zip"]
    out["install"] = args.get("install", "legacy")
    out["source_dir_on_path"] = [p for p in sys.path if os.path.normpath(os.path.abspath(p or ".")) == CLIENT_DIR]
    install_addon(os.path.abspath(args["zip"]), out["install"])
    livelink = find_addon_module()
    out["addon_file"] = livelink.__file__
    out["addon_module"] = livelink.__name__
    runtime = livelink.runtime
    scene = bpy.context.scene
    out["scene_fps_before"] = [scene.render.fps, scene.render.fps_base]
    settings = scene.rigcast
    out["default_address"] = settings.address
    out["default_transport"] = settings.transport
    out["default_color_mode"] = settings.color_mode
    panel = bpy.types.RIGCAST_PT_panel
    out["panel"] = {"space": panel.bl_space_type, "region": panel.bl_region_type, "category": panel.bl_category}
    settings.address = args["address"]
    settings.token = args.get("token", "")
    result = bpy.ops.rigcast.connect()
    if "FINISHED" not in result:
        raise RuntimeError("rigcast.connect returned %s" % result)

    observations = []
    pending = []
    num_ticks = [0]
    # Longest wall-clock wait between two ticks while recording: a key can only be made on a
    # tick, so the test bounds the gaps between keys by this, not by a guess at the load.
    max_tick_gap = [0.0]
    # Ticks made while recording: the rate the add-on could apply at is bounded by them.
    record_ticks = [0]
    # Scene-frame-long windows of wall-clock time holding at least one tick while recording:
    # the add-on can make at most one key in each, so a stalled Blender bounds the keys by it.
    frame_secs = scene.render.fps_base / scene.render.fps
    ticked_windows = set()

    def observer(subject_id, frame, obj):
        pending.append((subject_id, frame, obj))

    runtime.observers.append(observer)

    def pump(seconds, until=None, collect=False):
        tick_secs = 1.0 / 60.0
        start = time.monotonic()
        next_tick = start
        last_tick = start
        while time.monotonic() - start < seconds:
            now = time.monotonic()
            if collect:
                max_tick_gap[0] = max(max_tick_gap[0], now - last_tick)
            last_tick = now
            if collect:
                record_ticks[0] += 1
                ticked_windows.add(int(now / frame_secs))
            livelink.tick()
            if pending:
                if collect:
                    # Reading bone positions needs a depsgraph update, which costs more than
                    # applying; sample them every third tick so the measurement does not slow
                    # the very rate it measures. Seq and timestamps are kept for every frame.
                    with_heads = num_ticks[0] % 3 == 0
                    if with_heads:
                        bpy.context.view_layer.update()
                    for subject_id, frame, obj in pending:
                        record = observe(subject_id, frame, obj, with_heads)
                        # The scene frame this pose was keyed at (None: not keyed, a newer
                        # frame fell on an already keyed scene frame).
                        if runtime.recording:
                            record["keyed_frame"] = runtime.last_keyed.get(obj.name)
                        observations.append(record)
                del pending[:]
            num_ticks[0] += 1
            if until is not None and until():
                return True
            next_tick += tick_secs
            delay = next_tick - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        return until is None

    def have_skeletons():
        return runtime.hello is not None and all(
            s["id"] in runtime.skeletons for s in runtime.hello.get("subjects", [])
        )

    if not pump(10.0, have_skeletons):
        raise RuntimeError(
            "no hello/skeletons within 10 s; state=%r error=%r"
            % (runtime.status_text(), runtime.session and runtime.session.error)
        )
    out["hello"] = runtime.hello
    if args["mode"] == "connect":
        run_connect(out, runtime, settings, pump)
        return
    if args["mode"] == "mapping":
        run_mapping(out, runtime, settings, pump)
        return
    if args["mode"] == "footplants":
        run_footplants(out, runtime, settings, pump)
        return
    if args["mode"] == "record_failure":
        run_record_failure(out, runtime, settings, scene, pump)
        return
    subject_ids = [item.subject_id for item in settings.subjects]
    out["subject_ids"] = subject_ids
    for subject_id in subject_ids:
        result = bpy.ops.rigcast.create_armature(subject_id=subject_id)
        if "FINISHED" not in result:
            raise RuntimeError("create_armature(%d) returned %s" % (subject_id, result))
    out["armatures"] = {str(item.subject_id): item.armature.name for item in settings.subjects}
    out["rest_points"] = {}
    for item in settings.subjects:
        points = {}
        matrix_world = item.armature.matrix_world
        for bone in item.armature.data.bones:
            m = matrix_world @ bone.matrix_local
            z_point = m @ Vector((0.0, 0.0, bone.length))
            points[bone.name] = [list(m.to_translation()), list(matrix_world @ bone.tail_local), list(z_point)]
        out["rest_points"][str(item.subject_id)] = points

    # Bone colours by the mapping while streaming (the mapping test checks the values).
    if not pump(5.0, lambda: bool(runtime.mappings)):
        raise RuntimeError("no mapping message within 5 s")
    out["mapping_subjects"] = sorted(runtime.mappings)
    settings.color_mode = "GRADIENT"
    out["colored_bones"] = count_colored_bones(settings)

    pump(float(args["warmup"]))
    bpy.ops.rigcast.record()
    record_start = time.monotonic()
    pump(float(args["seconds"]), collect=True)
    # A loaded machine ticks Blender less often, so fewer poses are sampled in the same time;
    # keep recording (up to as long again) until every subject has enough sampled poses for
    # the test to compare with the frames the server sent.
    pump(float(args["seconds"]), lambda: enough_samples(observations, runtime), collect=True)
    bpy.ops.rigcast.record()
    out["record_secs"] = time.monotonic() - record_start
    out["max_tick_gap_secs"] = max_tick_gap[0]
    out["record_ticks"] = record_ticks[0]
    out["record_ticked_frames"] = len(ticked_windows)

    session = runtime.session
    out["session"] = {
        "received": session.num_frames_received,
        "skipped": session.num_frames_skipped,
        "missed": session.num_frames_missed,
        "bad": session.num_bad_frames,
        "connects": session.num_connects,
    }
    out["observations"] = observations
    out["scene_fps_after"] = [scene.render.fps, scene.render.fps_base]
    out["record_errors"] = dict(runtime.record_errors)
    out["actions"] = describe_actions(settings)
    out["playback"] = play_back(scene, settings, observations)
    bpy.ops.rigcast.disconnect()
    out["status_after_disconnect"] = runtime.status_text()


# Sampled poses (bone positions read) per subject the stream scenario collects at least.
MIN_SAMPLED_POSES = 40


def enough_samples(observations, runtime):
    subjects = [s["id"] for s in runtime.hello.get("subjects", [])]
    counts = {}
    for record in observations:
        if "heads" in record:
            counts[record["subject"]] = counts.get(record["subject"], 0) + 1
    return all(counts.get(s, 0) >= MIN_SAMPLED_POSES for s in subjects)


def observe(subject_id, frame, obj, with_heads):
    record = {"subject": subject_id}
    if frame is not None:
        record.update(
            seq=frame.seq,
            capture_nanos=frame.capture_nanos,
            received_nanos=frame.received_nanos,
            applied_nanos=time.time_ns(),
        )
    if not with_heads:
        return record
    # Three points per bone (head, tail, head + bone Z axis) pin its full orientation, twist
    # included; the Rust side predicts them from the rest points and forward kinematics.
    matrix_world = obj.matrix_world
    heads = {}
    for pose_bone in obj.pose.bones:
        m = matrix_world @ pose_bone.matrix
        z_point = m @ Vector((0.0, 0.0, pose_bone.length))
        heads[pose_bone.name] = [list(m.to_translation()), list(matrix_world @ pose_bone.tail), list(z_point)]
    record["heads"] = heads
    return record


def play_back(scene, settings, observations, per_subject=8):
    """Plays the recorded Actions back at keyed frames and reads the poses they produce.

    The caller compares each with forward kinematics of the server frame that was keyed there
    (found by seq), so "playback equals the recorded poses" is judged against the server, not
    against the add-on's own numbers.
    """
    samples = []
    by_subject = {item.subject_id: item.armature for item in settings.subjects}
    keyed = {}
    for record in observations:
        if record.get("keyed_frame") is not None:
            keyed.setdefault(record["subject"], []).append(record["keyed_frame"])
    for subject_id, frames in keyed.items():
        obj = by_subject.get(subject_id)
        if obj is None or obj.animation_data is None or obj.animation_data.action is None:
            continue
        step = max(1, len(frames) // per_subject)
        for frame in frames[1::step][:per_subject]:
            scene.frame_set(int(frame))
            bpy.context.view_layer.update()
            sample = observe(subject_id, None, obj, True)
            sample["frame"] = frame
            samples.append(sample)
    return samples


def _applied_fps(runtime, settings, pump, secs):
    """Poses applied per second per subject while pumping the add-on for `secs`."""
    before = {item.subject_id: runtime.stats[item.subject_id].num_applied for item in settings.subjects}
    started = time.monotonic()
    pump(secs)
    secs = time.monotonic() - started
    return {
        str(item.subject_id): (runtime.stats[item.subject_id].num_applied - before[item.subject_id]) / secs
        for item in settings.subjects
    }


def run_record_failure(out, runtime, settings, scene, pump):
    """One armature's take breaks mid-recording (its Action is deleted under it, as a user
    might in the Outliner): that take stops with one reported error, the others record on and
    every armature keeps receiving its live pose at the full rate."""
    for item in settings.subjects:
        result = bpy.ops.rigcast.create_armature(subject_id=item.subject_id)
        if "FINISHED" not in result:
            raise RuntimeError("create_armature(%d) returned %s" % (item.subject_id, result))
    pump(0.5)
    bpy.ops.rigcast.record()
    # The rate while every take records: the yardstick for "kept its rate" on a busy machine.
    out["applied_fps_before_break"] = _applied_fps(runtime, settings, pump, 1.0)
    broken = settings.subjects[0].armature.name
    take = runtime.takes.get(broken)
    if take is None:
        raise RuntimeError("no take for %s after 0.5 s of recording" % broken)
    bpy.data.actions.remove(take.action)
    out["applied_fps_after_break"] = _applied_fps(runtime, settings, pump, 2.0)
    bpy.ops.rigcast.record()
    out["broken_armature"] = broken
    out["record_errors"] = dict(runtime.record_errors)
    out["last_error"] = runtime.last_error
    out["actions"] = describe_actions(settings)
    bpy.ops.rigcast.disconnect()


def run_footplants(out, runtime, settings, pump):
    """The target's foot-lock state as the add-on exposes it: the armature's
    `rigcast_footplants` property and each foot bone's `rigcast_planted`, sampled every tick for
    a few seconds together with the seq of the `footplants` message behind it."""
    targets = [item for item in settings.subjects if item.kind == "target"]
    if not targets:
        raise RuntimeError("the server streams no target subject")
    target = targets[0]
    bpy.ops.rigcast.create_armature(subject_id=target.subject_id)
    obj = target.armature
    samples = []
    seen = set()

    def sample():
        message = runtime.footplants.get(target.subject_id)
        state = obj.get("rigcast_footplants")
        if message is None or state is None or message["seq"] in seen:
            return False
        seen.add(message["seq"])
        samples.append(
            {
                "seq": message["seq"],
                "property": {
                    bone: {"planted": int(v["planted"]), "position": list(v["position"])}
                    for bone, v in state.items()
                },
                "bone_planted": {
                    bone: int(obj.pose.bones[bone].get("rigcast_planted", -1)) for bone in state.keys()
                },
            }
        )
        return False

    pump(3.0, sample)
    out["target_subject"] = target.subject_id
    out["footplant_samples"] = samples
    bpy.ops.rigcast.disconnect()


def run_connect(out, runtime, settings, pump):
    """Default settings reach the server: hello, skeletons, and frames for every subject."""
    for item in settings.subjects:
        bpy.ops.rigcast.create_armature(subject_id=item.subject_id)

    def applied_everywhere():
        return all(runtime.stats[item.subject_id].num_applied >= 10 for item in settings.subjects)

    if not pump(10.0, applied_everywhere):
        raise RuntimeError("frames not applied to every subject within 10 s: %s" % runtime.status_text())
    session = runtime.session
    out["connect"] = {
        "status": runtime.status_text(),
        "connected": session.connected,
        "received": session.num_frames_received,
        "applied": {str(item.subject_id): runtime.stats[item.subject_id].num_applied for item in settings.subjects},
        "subjects": [item.name for item in settings.subjects],
        "mapping_rows": len(settings.mapping_items),
    }
    bpy.ops.rigcast.disconnect()
    out["status_after_disconnect"] = runtime.status_text()


def mapping_list(settings):
    """The add-on's mapping list as the panel shows it (with each row's icon and confidence
    text, from the same function its list draws with)."""
    marks = find_addon_module("ui").mapping_row_marks
    return [
        {
            "target": item.target,
            "source": item.source or None,
            "score": item.score,
            "confidence": item.confidence,
            "flagged": item.flagged or None,
            "icon": marks(item)[0],
            "confidence_text": marks(item)[1],
            "color_gradient": list(item.color_gradient),
            "color_random": list(item.color_random),
        }
        for item in settings.mapping_items
    ]


def bone_colors(obj):
    return {bone.name: list(bone_color(obj, bone.name)) for bone in obj.data.bones if bone_has_color(obj, bone.name)}


def run_mapping(out, runtime, settings, pump):
    """The real server mapping in the list, the colours on the bones, an override round trip."""
    targets = [item for item in settings.subjects if item.kind == "target"]
    if not targets:
        raise RuntimeError("the server streams no target subject")
    target = targets[0]
    if not pump(10.0, lambda: target.subject_id in runtime.mappings):
        raise RuntimeError("no mapping for subject %d within 10 s" % target.subject_id)
    # The user's steps: pick the target in the subject list (selects its mapping), create the
    # armatures from the subjects.
    settings.subject_index = [item.subject_id for item in settings.subjects].index(target.subject_id)
    source_id = target.source_id
    for subject_id in (target.subject_id, source_id):
        result = bpy.ops.rigcast.create_armature(subject_id=subject_id)
        if "FINISHED" not in result:
            raise RuntimeError("create_armature(%d) returned %s" % (subject_id, result))
    out["mapping_subject"] = settings.mapping_subject
    out["target_subject"] = target.subject_id
    out["source_subject"] = source_id
    out["list_before"] = mapping_list(settings)
    out["source_bone_choices"] = [b.name for b in settings.source_bones]
    by_id = {item.subject_id: item.armature for item in settings.subjects}
    for mode in ("GRADIENT", "RANDOM"):
        settings.color_mode = mode
        out["colors_" + mode.lower()] = {
            "target": bone_colors(by_id[target.subject_id]),
            "source": bone_colors(by_id[source_id]),
        }

    # Pick a mapped row (a flagged one, as a user checking the marked bones would, when there
    # is one), pick another source bone for it, send.
    items = list(settings.mapping_items)
    mapped = [i for i, item in enumerate(items) if item.source]
    flagged = [i for i in mapped if items[i].flagged]
    row = flagged[0] if flagged else mapped[len(mapped) // 2]
    settings.mapping_index = row
    out["picked_row"] = {
        "index": row,
        "target": items[row].target,
        "shown_source": settings.override_source,
        "flagged": items[row].flagged or None,
    }
    others = [b.name for b in settings.source_bones if b.name != items[row].source]
    new_source = others[len(others) // 3]
    settings.override_source = new_source
    out["override"] = {"target": items[row].target, "source": new_source}
    result = bpy.ops.rigcast.set_override()
    if "FINISHED" not in result:
        raise RuntimeError("set_override returned %s" % result)
    picked_target = items[row].target

    def list_shows_override():
        for item in settings.mapping_items:
            if item.target == picked_target:
                return item.source == new_source
        return False

    out["override_shown"] = pump(10.0, list_shows_override)
    out["list_after"] = mapping_list(settings)
    settings.color_mode = "GRADIENT"
    out["colors_after"] = {"target": bone_colors(by_id[target.subject_id])}
    out["last_error"] = runtime.last_error
    bpy.ops.rigcast.disconnect()


def bone_has_color(obj, name):
    if hasattr(obj.pose, "bone_groups"):
        return obj.pose.bones[name].bone_group is not None
    return obj.data.bones[name].color.palette == "CUSTOM"


def bone_color(obj, name):
    if hasattr(obj.pose, "bone_groups"):
        group = obj.pose.bones[name].bone_group
        return group.colors.normal if group else (0, 0, 0)
    return obj.data.bones[name].color.custom.normal


def count_colored_bones(settings):
    counts = {}
    for item in settings.subjects:
        obj = item.armature
        if obj is None:
            continue
        if hasattr(obj.pose, "bone_groups"):
            n = sum(1 for pb in obj.pose.bones if pb.bone_group is not None)
        else:
            n = sum(1 for b in obj.data.bones if b.color.palette == "CUSTOM")
        counts[str(item.subject_id)] = n
    return counts


def describe_actions(settings):
    actions = {}
    for item in settings.subjects:
        obj = item.armature
        if obj is None or obj.animation_data is None or obj.animation_data.action is None:
            continue
        action = obj.animation_data.action
        curves = []
        for fcurve in iter_fcurves(action):
            curves.append(
                {
                    "data_path": fcurve.data_path,
                    "index": fcurve.array_index,
                    "group": fcurve.group.name if fcurve.group else None,
                    "frames": [k.co[0] for k in fcurve.keyframe_points],
                    "values": [k.co[1] for k in fcurve.keyframe_points],
                }
            )
        slot = getattr(obj.animation_data, "action_slot", None)
        actions[str(item.subject_id)] = {
            "name": action.name,
            "fcurves": curves,
            "layered": bool(getattr(action, "layers", None)),
            # 4.4+: the slot the armature is bound to (None: unbound, plays nothing in 5.0).
            "slot": slot.identifier if slot is not None else None,
            "num_slots": len(action.slots) if hasattr(action, "slots") else None,
        }
    return actions


def iter_fcurves(action):
    # Blender 4.4+ keeps curves in layered channelbags; older versions in action.fcurves.
    if getattr(action, "layers", None):
        for layer in action.layers:
            for strip in layer.strips:
                for bag in getattr(strip, "channelbags", []):
                    yield from bag.fcurves
        return
    yield from action.fcurves


main()
