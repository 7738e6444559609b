//! N4SID followed by PEM (MATLAB's `ssest`).

use super::result::PemResult;
use super::search::pem;
use super::settings::PemSettings;
use crate::data::IoData;
use crate::error::Result;
use crate::n4sid::{N4sidResult, N4sidSettings, n4sid};

/// Result of [`pem_n4sid`]: the subspace start and the refined model.
#[derive(Clone, Debug, PartialEq)]
pub struct Identified {
    /// The N4SID start.
    pub start: N4sidResult,
    /// The prediction-error refinement.
    pub pem: PemResult,
}

/// N4SID followed by PEM from the N4SID model (MATLAB's `ssest`).
pub fn pem_n4sid(
    data: &IoData,
    start: &N4sidSettings,
    settings: &PemSettings,
) -> Result<Identified> {
    let mut s = start.clone();
    s.feedthrough = settings.feedthrough;
    let st = n4sid(data, &s)?;
    let p = pem(data, &st.model, settings)?;
    Ok(Identified { start: st, pem: p })
}
