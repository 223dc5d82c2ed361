"""Main-thread runtime: turns stream messages into Blender data (needs bpy and mathutils).

Rotation math (derivation in clients/blender/README.md). For skeleton bone i with rest local
rotation r_i, rest world rotation Wr_i (ours) and a Blender bone whose rest matrix in armature
space has rotation B_i, the per-bone axis offset is D_i = (C * Wr_i)^-1 * B_i, where C is the
+90 degree X rotation taking ours (+Y up) to Blender (+Z up). It absorbs Blender's convention
that bones point along local +Y, and any roll. A frame's full local rotation q_i then becomes

    pose_bone.rotation_quaternion = D_i^-1 * r_i^-1 * q_i * D_i

which is "the Blender bone's rest local rotation, inverted, times the converted local rotation"
written in the Blender bone's own axes. It requires the armature's rest pose to match the
subject's rest pose (true for armatures made by "Create armature from subject").
"""

import collections
import math
import time

import bpy
from mathutils import Matrix, Quaternion, Vector

from . import record as record_mod
from . import session as session_mod
from . import vmc as vmc_mod

C_OURS_TO_BLENDER = Quaternion((math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0))  # (w, x, y, z)
TICK_SECS = 1.0 / 60.0


def wire_quat(xyzw):
    return Quaternion((xyzw[3], xyzw[0], xyzw[1], xyzw[2]))


def vec_ours_to_blender(p):
    return Vector((p[0], -p[2], p[1]))


def rest_world(bones):
    """World (rotation, position) of each bone at rest, ours space; bones are parent-first."""
    rotations = []
    positions = []
    for bone in bones:
        r = wire_quat(bone["rest_rotation"])
        t = Vector(bone["rest_translation"])
        parent = bone.get("parent")
        if parent is None:
            rotations.append(r)
            positions.append(t)
        else:
            pr = rotations[parent]
            rotations.append(pr @ r)
            positions.append(positions[parent] + pr @ t)
    return rotations, positions


class BoneBinding:
    __slots__ = (
        "pose_bone",
        "left",
        "right",
        "root_rotation_inv",
        "root_head",
        "is_root",
        "index",
        "slot",
        "move_rotation",
        "rest_translation",
    )


class Binding:
    """Precomputed per-bone factors for one (subject skeleton, armature) pair."""

    def __init__(self, obj, skeleton):
        self.obj = obj
        self.fingerprint = skeleton.get("fingerprint", "")
        self.bones = []
        self.num_unmatched = 0
        bones = skeleton["bones"]
        world_rotations, _ = rest_world(bones)
        # Version 2 frames carry the translations of the bones marked `translated`, in order.
        slots = {}
        for index, bone in enumerate(bones):
            if bone.get("translated"):
                slots[index] = len(slots)
        self.num_translated = len(slots)
        arm_bones = obj.data.bones
        lookup = {b.name.lower(): b.name for b in arm_bones}
        for index, bone in enumerate(bones):
            name = bone["name"]
            blender_name = name if name in arm_bones else lookup.get(name.lower())
            if blender_name is None:
                self.num_unmatched += 1
                continue
            data_bone = arm_bones[blender_name]
            pose_bone = obj.pose.bones[blender_name]
            pose_bone.rotation_mode = "QUATERNION"
            b_rot = data_bone.matrix_local.to_quaternion()
            d = (C_OURS_TO_BLENDER @ world_rotations[index]).inverted() @ b_rot
            rest_local = wire_quat(bone["rest_rotation"])
            entry = BoneBinding()
            entry.index = index
            entry.pose_bone = pose_bone
            entry.left = d.inverted() @ rest_local.inverted()
            entry.right = d
            entry.is_root = bone.get("parent") is None and index == 0
            entry.root_rotation_inv = b_rot.inverted()
            entry.root_head = data_bone.matrix_local.to_translation()
            entry.slot = slots.get(index)
            # pose_bone.location is an offset from the rest head in the bone's rest axes: a
            # parent-local offset (ours) is turned into armature space by the parent's rest
            # world rotation, then into the bone's axes.
            parent = bone.get("parent")
            parent_rest = world_rotations[parent] if parent is not None else Quaternion()
            entry.move_rotation = b_rot.inverted() @ C_OURS_TO_BLENDER @ parent_rest
            entry.rest_translation = Vector(bone["rest_translation"])
            self.bones.append(entry)

    def apply(self, frame):
        rotations = frame.rotations
        for entry in self.bones:
            i = 4 * entry.index
            q = Quaternion((rotations[i + 3], rotations[i], rotations[i + 1], rotations[i + 2]))
            x = entry.left @ q @ entry.right
            previous = entry.pose_bone.rotation_quaternion
            # Keep the hemisphere continuous so recorded curves interpolate the short way.
            if previous.dot(x) < 0.0:
                x.negate()
            entry.pose_bone.rotation_quaternion = x
            if getattr(frame, "version", 1) == 2:
                if entry.slot is None:
                    continue
                t = Vector(frame.translation(entry.slot))
                if entry.is_root:
                    head = vec_ours_to_blender(t)
                    entry.pose_bone.location = entry.root_rotation_inv @ (head - entry.root_head)
                else:
                    entry.pose_bone.location = entry.move_rotation @ (t - entry.rest_translation)
            elif entry.is_root:
                head = vec_ours_to_blender(frame.root_translation)
                entry.pose_bone.location = entry.root_rotation_inv @ (head - entry.root_head)


class SubjectStats:
    def __init__(self):
        self.apply_times = collections.deque(maxlen=240)
        self.latency_ms = 0.0
        self.last_seq = None
        self.num_applied = 0

    def fps(self, now):
        while self.apply_times and now - self.apply_times[0] > 1.0:
            self.apply_times.popleft()
        return float(len(self.apply_times))


class Runtime:
    """All non-RNA state of the add-on (sockets, caches, statistics)."""

    def __init__(self):
        self.session = None
        self.vmc = None
        self.hello = None
        self.subjects = {}
        self.skeletons = {}
        self.mappings = {}
        self.footplants = {}  # target subject id -> latest `footplants` message
        self.bindings = {}
        self.stats = collections.defaultdict(SubjectStats)
        self.last_error = ""
        self.recording = False
        self.takes = {}  # armature name -> Take while recording
        self.record_errors = {}  # armature name -> why its take stopped
        self.last_keyed = {}  # armature name -> scene frame keyed by its latest frame, or None
        self.observers = []  # callables(subject_id, frame, obj); used by tests
        self.last_redraw = 0.0
        self.vmc_binding = None

    # -- connection ------------------------------------------------------------------------

    def connect(self, settings):
        self.disconnect()
        if settings.transport == "VMC":
            self.vmc = vmc_mod.VmcReceiver(settings.vmc_port)
        else:
            self.session = session_mod.StreamSession(
                settings.address, settings.auto_reconnect, settings.token.strip()
            )
            self.session.start()
        ensure_timer()

    def disconnect(self):
        if self.session is not None:
            self.session.stop()
            self.session = None
        if self.vmc is not None:
            self.vmc.close()
            self.vmc = None
        self.vmc_binding = None

    def status_text(self):
        if self.session is not None:
            return self.session.state
        if self.vmc is not None:
            return "VMC listening, %d packets" % self.vmc.num_packets
        return "not connected"

    # -- per tick --------------------------------------------------------------------------

    def tick(self, scene):
        settings = scene.rigcast
        if self.session is not None:
            for message in self.session.take_messages():
                self.handle_message(settings, message)
            frames = self.session.take_frames()
            if frames:
                self.apply_frames(scene, settings, frames)
        if self.vmc is not None and self.vmc.poll():
            self.apply_vmc(scene, settings)
        now = time.monotonic()
        if now - self.last_redraw > 0.25:
            self.last_redraw = now
            redraw_panels()

    def handle_message(self, settings, message):
        kind = message.get("type")
        if kind == "hello":
            self.hello = message
            self.set_subjects(settings, message.get("subjects") or [])
        elif kind == "subjects_changed":
            self.set_subjects(settings, message.get("subjects") or [])
        elif kind == "skeleton":
            subject = message.get("subject")
            if isinstance(subject, int) and isinstance(message.get("bones"), list):
                self.skeletons[subject] = message
                self.bindings = {k: v for k, v in self.bindings.items() if k[0] != subject}
                if settings.mapping_subject == subject or settings.mapping_subject < 0:
                    refresh_mapping_ui(settings, self)
        elif kind == "mapping":
            subject = message.get("subject")
            if isinstance(subject, int):
                self.mappings[subject] = message
                refresh_mapping_ui(settings, self)
                color_mode = settings.color_mode
                if color_mode != "NONE":
                    apply_mapping_colors(settings, self, color_mode)
        elif kind == "footplants":
            subject = message.get("subject")
            if isinstance(subject, int) and isinstance(message.get("feet"), list):
                self.footplants[subject] = message
                self.show_footplants(settings, subject)
        elif kind == "error":
            self.last_error = "%s: %s" % (message.get("code", "?"), message.get("message", ""))
        elif kind == "_disconnected":
            self.last_error = message.get("reason", "")

    def show_footplants(self, settings, subject):
        """Exposes a target's foot-lock state on its armature as custom properties:

        - `obj["rigcast_footplants"]`: {foot bone: {"planted": 0/1, "position": (x, y, z)}}, the
          position in the armature's space (Blender axes), where the lock pins the foot;
        - `pose_bone["rigcast_planted"]`: 0/1 on each foot bone (usable in drivers).

        Integers rather than booleans: Blender 3.4's ID properties have no boolean type.
        """
        message = self.footplants.get(subject)
        if message is None:
            return
        for item in settings.subjects:
            obj = item.armature
            if item.subject_id != subject or obj is None or obj.type != "ARMATURE":
                continue
            state = {}
            for foot in message["feet"]:
                if not isinstance(foot, dict) or not isinstance(foot.get("bone"), str):
                    continue
                position = foot.get("position")
                if not (isinstance(position, list) and len(position) == 3):
                    continue
                planted = 1 if foot.get("planted") is True else 0
                state[foot["bone"]] = {"planted": planted, "position": tuple(vec_ours_to_blender(position))}
                pose_bone = obj.pose.bones.get(foot["bone"])
                if pose_bone is not None:
                    pose_bone["rigcast_planted"] = planted
            obj["rigcast_footplants"] = state

    def set_subjects(self, settings, subjects):
        assigned = {item.subject_id: item.armature for item in settings.subjects}
        settings.subjects.clear()
        for info in subjects:
            if not isinstance(info, dict) or not isinstance(info.get("id"), int):
                continue
            self.subjects[info["id"]] = info
            item = settings.subjects.add()
            item.subject_id = info["id"]
            item.name = str(info.get("name", "subject %d" % info["id"]))
            item.kind = str(info.get("kind", "source"))
            item.num_bones = int(info.get("num_bones") or 0)
            source = info.get("source")
            item.source_id = source if isinstance(source, int) else -1
            if assigned.get(info["id"]) is not None:
                item.armature = assigned[info["id"]]
        if settings.mapping_subject < 0:
            for item in settings.subjects:
                if item.kind == "target":
                    settings.mapping_subject = item.subject_id
                    break

    def binding_for(self, subject_id, obj):
        skeleton = self.skeletons.get(subject_id)
        if skeleton is None:
            return None
        key = (subject_id, obj.name)
        binding = self.bindings.get(key)
        if binding is None or binding.obj != obj:
            binding = Binding(obj, skeleton)
            self.bindings[key] = binding
        return binding

    def apply_frames(self, scene, settings, frames):
        now_nanos = time.time_ns()
        now = time.monotonic()
        for item in settings.subjects:
            frame = frames.get(item.subject_id)
            obj = item.armature
            if frame is None or obj is None or obj.type != "ARMATURE" or not item.live:
                continue
            stats = self.stats[item.subject_id]
            if frame.seq == stats.last_seq:
                # The server re-sends the newest frame when its tick outpaces the source; the
                # pose is unchanged, so neither apply nor record it again.
                continue
            binding = self.binding_for(item.subject_id, obj)
            if binding is None:
                continue
            skeleton = self.skeletons[item.subject_id]
            if frame.num_bones != len(skeleton["bones"]):
                self.last_error = "frame for subject %d has %d bones, skeleton has %d" % (
                    item.subject_id,
                    frame.num_bones,
                    len(skeleton["bones"]),
                )
                continue
            if frame.version == 2 and len(frame.translations) != 3 * binding.num_translated:
                self.last_error = "frame for subject %d carries %d translations, skeleton marks %d" % (
                    item.subject_id,
                    len(frame.translations) // 3,
                    binding.num_translated,
                )
                continue
            try:
                binding.apply(frame)
            except Exception as exc:
                # One broken armature (a bone deleted under the binding) must not stop the
                # others; the binding is rebuilt on the next frame.
                self.bindings.pop((item.subject_id, obj.name), None)
                self.last_error = "applying subject %d to %s failed: %s" % (item.subject_id, obj.name, exc)
                continue
            stats.apply_times.append(now)
            stats.num_applied += 1
            stats.last_seq = frame.seq
            latency_ms = (now_nanos - frame.capture_nanos) / 1e6
            stats.latency_ms = latency_ms if stats.num_applied == 1 else 0.9 * stats.latency_ms + 0.1 * latency_ms
            if self.recording:
                self.record(scene, obj, binding, frame.capture_nanos)
            for observer in self.observers:
                observer(item.subject_id, frame, obj)

    def apply_vmc(self, scene, settings):
        obj = settings.vmc_armature
        if obj is None or obj.type != "ARMATURE":
            return
        if self.vmc_binding is None or self.vmc_binding.obj != obj:
            self.vmc_binding = VmcBinding(obj)
        self.vmc_binding.apply(self.vmc.pose)
        if self.recording:
            self.record(scene, obj, self.vmc_binding, self.vmc.pose.received_nanos)

    # -- recording -------------------------------------------------------------------------

    def start_recording(self, scene):
        self.recording = True
        self.takes = {}
        self.record_errors = {}
        self.last_keyed = {}

    def stop_recording(self):
        """Finishes every take and assigns each Action to its armature."""
        self.recording = False
        for name, take in self.takes.items():
            try:
                take.finish()
            except Exception as exc:
                self.note_record_error(name, "finishing the take", exc)
        self.takes = {}

    def record(self, scene, obj, binding, capture_nanos):
        """Keys one armature's pose. A failure stops that armature's take only, once.

        Recording must never cost the live pose: an exception raised every tick (an API this
        Blender lacks, a removed Action) would otherwise repeat at the display rate and starve
        the other armatures of their frames.
        """
        if obj.name in self.record_errors:
            return
        try:
            take = self.takes.get(obj.name)
            if take is None:
                take = record_mod.Take(obj, scene, capture_nanos)
                self.takes[obj.name] = take
            keyed = take.add(binding, capture_nanos)
            self.last_keyed[obj.name] = keyed
        except Exception as exc:
            self.takes.pop(obj.name, None)
            self.note_record_error(obj.name, "recording", exc)

    def note_record_error(self, name, what, exc):
        message = "%s %s failed: %s: %s" % (what, name, type(exc).__name__, exc)
        self.record_errors[name] = message
        self.last_error = message
        print("rigcast:", message)


class VmcBinding:
    """VMC bones by name (HumanBodyBones, case-insensitive) onto an armature at T-pose rest.

    VMC rotations are relative to a VRM-normalised T-pose whose rest local rotations are all
    identity, so the offset reduces to D_i = C^-1 * B_i.
    """

    def __init__(self, obj):
        self.obj = obj
        self.by_name = {}
        for data_bone in obj.data.bones:
            pose_bone = obj.pose.bones[data_bone.name]
            pose_bone.rotation_mode = "QUATERNION"
            d = C_OURS_TO_BLENDER.inverted() @ data_bone.matrix_local.to_quaternion()
            entry = BoneBinding()
            entry.pose_bone = pose_bone
            entry.left = d.inverted()
            entry.right = d
            entry.is_root = data_bone.parent is None
            entry.root_rotation_inv = data_bone.matrix_local.to_quaternion().inverted()
            entry.root_head = data_bone.matrix_local.to_translation()
            entry.index = 0
            self.by_name[data_bone.name.lower()] = entry
        self.bones = list(self.by_name.values())

    def apply(self, pose):
        for name, (position, rotation) in pose.bones.items():
            entry = self.by_name.get(name.lower())
            if entry is None:
                continue
            q = Quaternion((rotation[3], rotation[0], rotation[1], rotation[2]))
            entry.pose_bone.rotation_quaternion = entry.left @ q @ entry.right
            if entry.is_root:
                head = vec_ours_to_blender(position)
                entry.pose_bone.location = entry.root_rotation_inv @ (head - entry.root_head)



# -- armature creation ---------------------------------------------------------------------


def create_armature(context, skeleton, name):
    """Builds an armature whose rest pose is the subject's rest pose (see module doc)."""
    bones = skeleton["bones"]
    _, positions = rest_world(bones)
    heads = [vec_ours_to_blender(p) for p in positions]
    children = [[] for _ in bones]
    for index, bone in enumerate(bones):
        if bone.get("parent") is not None:
            children[bone["parent"]].append(index)
    descendants = [0] * len(bones)
    for index in reversed(range(len(bones))):
        for child in children[index]:
            descendants[index] += 1 + descendants[child]

    if context.object is not None and context.object.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    data = bpy.data.armatures.new(name)
    obj = bpy.data.objects.new(name, data)
    context.scene.collection.objects.link(obj)
    obj.show_in_front = True
    context.view_layer.objects.active = obj
    obj.select_set(True)
    bpy.ops.object.mode_set(mode="EDIT")
    edit_bones = []
    directions = [Vector((0.0, 0.0, 1.0))] * len(bones)
    lengths = [0.1] * len(bones)
    for index, bone in enumerate(bones):
        head = heads[index]
        parent = bone.get("parent")
        # Point at the child carrying the most of the tree (the spine, not a leg, for hips).
        target = None
        for child in sorted(children[index], key=lambda c: -descendants[c]):
            if (heads[child] - head).length > 1e-3:
                target = child
                break
        if target is not None:
            offset = heads[target] - head
            directions[index] = offset.normalized()
            lengths[index] = offset.length
        elif parent is not None:
            directions[index] = directions[parent]
            lengths[index] = max(0.5 * lengths[parent], 0.03)
        edit_bone = data.edit_bones.new(bone["name"])
        edit_bone.head = head
        edit_bone.tail = head + directions[index] * max(lengths[index], 0.01)
        if parent is not None:
            edit_bone.parent = edit_bones[parent]
            edit_bone.use_connect = False
        edit_bones.append(edit_bone)
    bpy.ops.object.mode_set(mode="OBJECT")
    return obj


# -- mapping UI and colours ----------------------------------------------------------------


def refresh_mapping_ui(settings, runtime):
    mapping = runtime.mappings.get(settings.mapping_subject)
    settings.mapping_items.clear()
    settings.source_bones.clear()
    if mapping is None:
        return
    for entry in mapping.get("entries") or []:
        if not isinstance(entry, dict):
            continue
        item = settings.mapping_items.add()
        item.target = str(entry.get("target", ""))
        source = entry.get("source")
        item.source = source if isinstance(source, str) else ""
        score = entry.get("score")
        item.score = float(score) if isinstance(score, (int, float)) else 0.0
        # Older servers send no confidence: full, as the protocol reads it.
        confidence = entry.get("confidence", 1.0)
        item.confidence = float(confidence) if isinstance(confidence, (int, float)) else 1.0
        flagged = entry.get("flagged")
        item.flagged = flagged if isinstance(flagged, str) else ""
        item.color_gradient = _color(entry.get("color_gradient"))
        item.color_random = _color(entry.get("color_random"))
    skeleton = runtime.skeletons.get(mapping.get("source_subject"))
    if skeleton is not None:
        for bone in skeleton["bones"]:
            settings.source_bones.add().name = bone["name"]


def _color(value):
    if isinstance(value, list) and len(value) == 3 and all(isinstance(v, (int, float)) for v in value):
        return tuple(float(max(0.0, min(1.0, v))) for v in value)
    return (0.5, 0.5, 0.5)


def apply_mapping_colors(settings, runtime, mode):
    """Colours target bones by their mapping entry and source bones like the target they drive."""
    for target_id, mapping in runtime.mappings.items():
        key = "color_gradient" if mode == "GRADIENT" else "color_random"
        target_colors = {}
        source_colors = {}
        for entry in mapping.get("entries") or []:
            if not isinstance(entry, dict):
                continue
            color = _color(entry.get(key)) if mode != "NONE" else None
            target_colors[str(entry.get("target", ""))] = color
            if isinstance(entry.get("source"), str):
                source_colors[entry["source"]] = color
        for item in settings.subjects:
            if item.armature is None or item.armature.type != "ARMATURE":
                continue
            if item.subject_id == target_id:
                color_bones(item.armature, target_colors)
            elif item.subject_id == mapping.get("source_subject"):
                color_bones(item.armature, source_colors)


def color_bones(obj, colors):
    """Bone colours: bone groups in Blender 3.x, per-bone colours in 4.x."""
    bones = obj.data.bones
    if hasattr(obj.pose, "bone_groups"):
        groups = obj.pose.bone_groups
        for name, color in colors.items():
            if name not in bones:
                continue
            pose_bone = obj.pose.bones[name]
            if color is None:
                pose_bone.bone_group = None
                continue
            group_name = "rigcast %02x%02x%02x" % tuple(int(c * 255) for c in color)
            group = groups.get(group_name) or groups.new(name=group_name)
            group.color_set = "CUSTOM"
            group.colors.normal = color
            group.colors.select = tuple(min(1.0, c + 0.3) for c in color)
            group.colors.active = tuple(min(1.0, c + 0.5) for c in color)
            pose_bone.bone_group = group
    else:
        for name, color in colors.items():
            if name not in bones:
                continue
            bone_color = bones[name].color
            if color is None:
                bone_color.palette = "DEFAULT"
                continue
            bone_color.palette = "CUSTOM"
            bone_color.custom.normal = color
            bone_color.custom.select = tuple(min(1.0, c + 0.3) for c in color)
            bone_color.custom.active = tuple(min(1.0, c + 0.5) for c in color)


# -- timer ---------------------------------------------------------------------------------

runtime = Runtime()


def current_scene():
    scene = getattr(bpy.context, "scene", None)
    if scene is None and bpy.data.scenes:
        scene = bpy.data.scenes[0]
    return scene


def tick():
    """The display-rate timer: drain, apply the newest frame per subject, repeat."""
    scene = current_scene()
    if scene is None:
        return TICK_SECS
    try:
        runtime.tick(scene)
    except Exception as exc:  # never let one bad tick kill the timer (the UI would freeze)
        runtime.last_error = "tick failed: %s" % exc
    if runtime.session is None and runtime.vmc is None:
        return None
    return TICK_SECS


def ensure_timer():
    if not bpy.app.timers.is_registered(tick):
        bpy.app.timers.register(tick, first_interval=0.0, persistent=True)


def stop_timer():
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)


def redraw_panels():
    wm = getattr(bpy.context, "window_manager", None)
    if wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()
