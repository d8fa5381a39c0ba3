//! What the pager does when a block cannot be made resident: the executor's typed error
//! ([`ResidencyError`], returned by `plan::Residency::apply`) and the pager's decision ([`Retry`]), made
//! from the error's type and the same for a source's error ([`super::SourceError::is_transient`]).

use crate::ids::BlockId;

/// How soon the pager asks again for a block whose load failed (paper §6: a missing block is drawn with
/// its nearest resident ancestor meanwhile; the failure is counted).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Retry {
    /// The failure may pass (I/O, a corrupt transfer, a device hiccup): not requested again for
    /// `retry_frames × 2^failures` frames, the doubling capped at 64×.
    BackOff,
    /// Asking again soon cannot help (no free layer, a block the executor cannot use, a permanent source
    /// error): not requested again for the longest back-off, `64 × retry_frames` frames. Never forever:
    /// layers free up as blocks are evicted, and a server may be fixed.
    GiveUp,
}

impl Retry {
    /// [`Retry::BackOff`] for a transient failure, [`Retry::GiveUp`] otherwise.
    pub fn transient(transient: bool) -> Retry {
        if transient {
            Retry::BackOff
        } else {
            Retry::GiveUp
        }
    }
}

/// Why an executor could not apply a residency change (upload a loaded block, free an evicted one).
#[derive(Debug, thiserror::Error)]
pub enum ResidencyError {
    /// Every layer the block could go to is in use: retrying before a block is evicted is useless.
    #[error("{what}: {needed} layers needed, {limit} available")]
    NoFreeLayer {
        what: String,
        needed: u64,
        limit: u64,
    },
    /// The block's bytes cannot be used as its table describes (shorter than its mip chains, an unknown
    /// tree): the same bytes will fail again.
    #[error(
        "{block}: its bytes cannot be uploaded (shorter than its mip chains or not in a loaded tree)"
    )]
    BadBlock { block: BlockId },
    /// The executor's bookkeeping disagrees with the pager's (a bug, reported instead of drawing a wrong
    /// texture).
    #[error("residency bookkeeping broken: {message}")]
    Bookkeeping { message: String },
    /// The upload itself failed (device or driver error); may pass.
    #[error("upload failed: {message}")]
    Upload { message: String },
}

impl ResidencyError {
    /// Whether applying the same change again later may succeed (only [`ResidencyError::Upload`]).
    pub fn is_transient(&self) -> bool {
        matches!(self, ResidencyError::Upload { .. })
    }

    /// The pager's decision for a load that failed with this error.
    pub fn retry(&self) -> Retry {
        Retry::transient(self.is_transient())
    }
}
