//! The crate's typed errors.

/// What can go wrong building or viewing an IBRR.
#[derive(Debug, thiserror::Error)]
pub enum IbrrError {
    /// The layered depth cube would outgrow its memory budget ([`crate::IbrrSettings::max_bytes`]);
    /// raised before the allocation that would exceed it, and nothing built is kept.
    #[error("LDC memory budget exceeded: {needed} bytes needed, {limit} allowed ({what})")]
    Budget {
        /// Bytes the LDC would hold after the allocation.
        needed: u64,
        /// The budget.
        limit: u64,
        /// What was being allocated.
        what: String,
    },
    /// A setting is out of range (named in the message).
    #[error("invalid IBRR setting: {0}")]
    Settings(String),
    /// The scene, the light state or the G-buffer renderer failed.
    #[error(transparent)]
    Core(#[from] scene_core::Error),
}

impl From<IbrrError> for scene_core::Error {
    fn from(e: IbrrError) -> Self {
        match e {
            IbrrError::Core(e) => e,
            e => scene_core::Error::method("ibrr-ldc", e),
        }
    }
}
