"""Writes a copy of a BlazePose landmark model that computes only what rigcast reads.

Usage: prune_landmark_model.py IN.onnx OUT.onnx

The converted model has five outputs: landmarks (Identity), pose presence (Identity_1),
segmentation mask (Identity_2, 256x256), heatmaps (Identity_3, 64x64x39) and world landmarks
(Identity_4). ONNX Runtime runs every node of a graph whatever outputs a caller asks for, and
the mask and heatmap decoders (upsampling convolutions at high resolution) are about half the
model's work. Keeping only the subgraph behind the outputs rigcast uses gives the same numbers
(the kept nodes and weights are untouched) in about half the time. The heatmaps are kept (since
the setup's derivation 3): rigcast refines the body's landmarks from them, as MediaPipe does,
for about a tenth more work a run than the three other outputs alone.

The copy's batch dimension is left open (the converted model fixes it at 1, but its reshapes
already take any batch), so rigcast can run the crops of every tracked person in one call.
"""
import sys

import onnx
import onnx.utils

KEEP = ["Identity", "Identity_1", "Identity_4", "Identity_3"]

src, dst = sys.argv[1], sys.argv[2]
model = onnx.load(src)
names = [o.name for o in model.graph.output]
missing = [n for n in KEEP if n not in names]
if missing:
    sys.exit(f"{src}: no output(s) {missing} (has {names}); not a BlazePose landmark model?")
inputs = [i.name for i in model.graph.input]
pruned = onnx.utils.Extractor(model).extract_model(inputs, KEEP)
for value in list(pruned.graph.input) + list(pruned.graph.output):
    value.type.tensor_type.shape.dim[0].dim_param = "batch"
# Inferred intermediate shapes still say batch 1; the runtime infers them again.
del pruned.graph.value_info[:]
onnx.checker.check_model(pruned)
onnx.save(pruned, dst)
print(f"{src}: {len(model.graph.node)} -> {len(pruned.graph.node)} nodes")
