//! Why something the engine prepares (a live graft, an idle graph) cannot run: a message that
//! reads as a sentence, with what it was doing first. The host adds which performer or file.

use std::fmt;

/// Why a live graft or an idle graph could not be prepared.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PrepareError(String);

impl PrepareError {
    /// An error saying `why`.
    pub fn new(why: impl Into<String>) -> PrepareError {
        PrepareError(why.into())
    }

    /// This error behind `what` was being done: `what: why`.
    pub fn within(self, what: impl fmt::Display) -> PrepareError {
        PrepareError(format!("{what}: {}", self.0))
    }
}

impl fmt::Display for PrepareError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for PrepareError {}

/// `Result` with a [`PrepareError`].
pub type PrepareResult<T> = Result<T, PrepareError>;

/// Turns any error into a [`PrepareError`] saying `what` failed and why.
pub(crate) fn failed<E: fmt::Display>(what: &'static str) -> impl FnOnce(E) -> PrepareError {
    move |e| PrepareError(format!("{what}: {e}"))
}
