//! An agent's payload as the frame the ingest checks: a frame, or an ETSI CPM read as one
//! (docs/cpm.md).

use crate::intake::ingest::Rejection;
use v2x_cpm::Geo;
use v2x_protocol::Frame;

/// The frame a payload heard on `agent`'s key carries: a CPM when its encoding says so
/// (`cpm`), else a frame. A CPM's objects of classes without a name here go to `unnamed`.
pub(super) fn decode(
    cpm: bool,
    agent: &str,
    payload: &[u8],
    geo: &Geo,
    unnamed: &std::cell::Cell<u64>,
) -> Result<Frame, Rejection> {
    if cpm {
        frame(agent, payload, geo, unnamed)
    } else {
        v2x_protocol::wire::decode(payload).map_err(Rejection::Invalid)
    }
}

/// The frame a CPM heard on `agent`'s key carries; its station id must be the agent's.
fn frame(
    agent: &str,
    payload: &[u8],
    geo: &Geo,
    unnamed: &std::cell::Cell<u64>,
) -> Result<Frame, Rejection> {
    let cpm = v2x_cpm::decode(payload, geo).map_err(|e| Rejection::InvalidCpm(e.to_string()))?;
    if cpm.station_id != v2x_cpm::station_id(agent) {
        return Err(Rejection::WrongAgent(format!("station {}", cpm.station_id)));
    }
    unnamed.set(cpm.skipped.len() as u64);
    Ok(cpm.into_frame(agent.to_string()))
}
