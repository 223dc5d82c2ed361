"""Turns the BlazePose detector's sparse fp16 weights into plain float32 constants.

The shipped model stores weights as sparse float16 tensors expanded at load time by DENSIFY and
DEQUANTIZE ops, which the TFLite→ONNX converter cannot read. TFLite itself evaluates them: run
the interpreter once, read each such op's output, store it as a float32 constant, drop the op.
"""
import sys
import numpy as np
import tensorflow as tf
from tensorflow.lite.tools import flatbuffer_utils as fu
from tensorflow.lite.python import schema_py_generated as S

src, dst = sys.argv[1], sys.argv[2]
model = fu.read_model(src)
graph = model.subgraphs[0]
codes = [max(c.builtinCode, c.deprecatedBuiltinCode) for c in model.operatorCodes]
expand = {S.BuiltinOperator.DENSIFY, S.BuiltinOperator.DEQUANTIZE}

interp = tf.lite.Interpreter(
    model_path=src,
    experimental_preserve_all_tensors=True,
    # The XNNPACK delegate would take the ops over and leave their outputs unread.
    experimental_op_resolver_type=tf.lite.experimental.OpResolverType.BUILTIN_WITHOUT_DEFAULT_DELEGATES,
)
interp.allocate_tensors()
inp = interp.get_input_details()[0]
interp.set_tensor(inp["index"], np.zeros(inp["shape"], np.float32))
interp.invoke()

kept, folded = [], 0
for op in graph.operators:
    if codes[op.opcodeIndex] not in expand:
        kept.append(op)
        continue
    out = op.outputs[0]
    value = interp.get_tensor(out).astype(np.float32)
    model.buffers.append(S.BufferT())
    model.buffers[-1].data = np.frombuffer(value.tobytes(), np.uint8)
    t = graph.tensors[out]
    t.buffer = len(model.buffers) - 1
    t.type = S.TensorType.FLOAT32
    folded += 1
graph.operators = kept
# Inputs of the dropped ops are no longer read; empty them so no converter tries to.
used = {i for op in kept for i in op.inputs} | set(graph.inputs) | set(graph.outputs)
for i, t in enumerate(graph.tensors):
    if i not in used and t.sparsity is not None:
        t.sparsity = None
        model.buffers[t.buffer].data = None
        t.buffer = 0
fu.write_model(model, dst)
print(f"folded {folded} ops, {len(kept)} left")
