//! [`BoundRun`]: a model run whose input and output tensors are all allocated once, when the
//! model is loaded.
//!
//! Why not `Session::run`: on every call it collects the input and output names and values
//! into lists and wraps each output in a reference-counted value, which is six heap
//! allocations per landmark model run on our side (measured in `tests/vision_alloc.rs`), on a
//! path that runs once per tracked person per frame. Here the names are C strings made at load
//! time, the pointer arrays live on the stack, and ONNX Runtime writes the outputs into tensors
//! we own (it accepts pre-allocated outputs of the exact shape), so a run allocates nothing on
//! the Rust side. What ONNX Runtime allocates inside its C++ code is not ours to change.

use std::ffi::{c_char, CStr, CString};
use std::path::{Path, PathBuf};

use ort::session::Session;
use ort::value::{Tensor, ValueType};
use ort::AsPointer;

use super::error::VisionError;

/// `N` bound outputs of `f32`, read back in place after each run.
pub(crate) struct BoundRun<const N: usize> {
    path: PathBuf,
    input_name: CString,
    output_names: [CString; N],
    outputs: [Tensor<f32>; N],
}

impl<const N: usize> std::fmt::Debug for BoundRun<N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BoundRun")
            .field("path", &self.path)
            .finish()
    }
}

impl<const N: usize> BoundRun<N> {
    /// Binds `session`'s first input and the outputs `names` for runs on `batch` inputs at
    /// once; each output must hold `lengths[i]` values per input (a model whose outputs differ
    /// is refused here, not at the first frame). Output shapes come from the model: a dynamic
    /// first dimension is the batch, other dynamic dimensions are taken as 1.
    pub(crate) fn new(
        session: &Session,
        path: &Path,
        names: [&'static str; N],
        lengths: [usize; N],
        batch: usize,
    ) -> Result<Self, VisionError> {
        let input = session
            .inputs()
            .first()
            .ok_or_else(|| model_err(path, "the model has no input"))?;
        let input_name = CString::new(input.name()).map_err(|e| model_err(path, e))?;
        let mut outputs = Vec::with_capacity(N);
        let mut output_names = Vec::with_capacity(N);
        for (name, per_input) in names.into_iter().zip(lengths) {
            let expected = per_input * batch;
            let shape = output_shape(session, name, batch)
                .ok_or_else(|| model_err(path, format!("no float tensor output {name}")))?;
            let actual = shape.iter().product::<i64>() as usize;
            check_len(name, actual, expected)?;
            let tensor = Tensor::from_array((shape, vec![0.0f32; expected]))
                .map_err(|e| model_err(path, e))?;
            outputs.push(tensor);
            output_names.push(CString::new(name).map_err(|e| model_err(path, e))?);
        }
        // Exactly N of each were pushed above.
        let outputs: [Tensor<f32>; N] = outputs
            .try_into()
            .map_err(|_| model_err(path, "output count"))?;
        let output_names: [CString; N] = output_names
            .try_into()
            .map_err(|_| model_err(path, "output count"))?;
        Ok(BoundRun {
            path: path.to_path_buf(),
            input_name,
            output_names,
            outputs,
        })
    }

    /// Runs `session` on `input`; afterwards [`Self::output`] holds the results.
    pub(crate) fn run(
        &mut self,
        session: &mut Session,
        input: &Tensor<f32>,
    ) -> Result<(), VisionError> {
        let input_names = [self.input_name.as_ptr()];
        let inputs = [input.ptr()];
        let output_names: [*const c_char; N] =
            std::array::from_fn(|i| self.output_names[i].as_ptr());
        let mut outputs: [*mut ort::sys::OrtValue; N] =
            std::array::from_fn(|i| self.outputs[i].ptr_mut());
        let api = ort::api();
        // SAFETY: every pointer is valid for the call: the session and the tensors are owned
        // by `self`/the caller and outlive it, the name arrays point to NUL-terminated strings
        // owned by `self`, and the lengths are the arrays' own. Non-null output values are
        // filled in place (ONNX Runtime's documented pre-allocated output contract); their
        // shapes were checked against the model when bound. `&mut Session` keeps runs of one
        // session from overlapping (ONNX Runtime's Run is not safe to call concurrently).
        let status = unsafe {
            (api.Run)(
                session.ptr_mut(),
                std::ptr::null(),
                input_names.as_ptr(),
                inputs.as_ptr(),
                inputs.len(),
                output_names.as_ptr(),
                N,
                outputs.as_mut_ptr(),
            )
        };
        if status.0.is_null() {
            return Ok(());
        }
        // SAFETY: a non-null status is a live OrtStatus until released below; its message is
        // a NUL-terminated string owned by it, copied before the release.
        let message = unsafe {
            let text = CStr::from_ptr((api.GetErrorMessage)(status.0))
                .to_string_lossy()
                .into_owned();
            (api.ReleaseStatus)(status.0);
            text
        };
        Err(model_err(&self.path, message))
    }

    /// Output `i` of the last run.
    pub(crate) fn output(&self, i: usize) -> &[f32] {
        self.outputs[i].extract_tensor().1
    }
}

/// The shape of float output `name` for `batch` inputs: a dynamic first dimension is the
/// batch, other dynamic dimensions 1.
pub(crate) fn output_shape(session: &Session, name: &str, batch: usize) -> Option<Vec<i64>> {
    let outlet = session.outputs().iter().find(|o| o.name() == name)?;
    match outlet.dtype() {
        ValueType::Tensor { ty, shape, .. } if *ty == ort::value::TensorElementType::Float32 => {
            Some(
                shape
                    .iter()
                    .enumerate()
                    .map(|(i, &d)| match (i, d < 0) {
                        (0, true) => batch as i64,
                        _ => d.max(1),
                    })
                    .collect(),
            )
        }
        _ => None,
    }
}

/// Whether `session`'s first input takes a batch of any size (its first dimension is
/// dynamic), so several crops can run in one call.
pub(crate) fn takes_batches(session: &Session) -> bool {
    session
        .inputs()
        .first()
        .is_some_and(|input| match input.dtype() {
            ValueType::Tensor { shape, .. } => shape.first().is_some_and(|&d| d < 0),
            _ => false,
        })
}

/// A model file's error, naming the file.
pub(crate) fn model_err(path: &Path, e: impl std::fmt::Display) -> VisionError {
    VisionError::Model {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// An output's length against the shape the model declared.
pub(crate) fn check_len(
    name: &'static str,
    actual: usize,
    expected: usize,
) -> Result<(), VisionError> {
    if actual == expected {
        Ok(())
    } else {
        Err(VisionError::OutputShape {
            name,
            expected,
            actual,
        })
    }
}
