//! The node's admission limits.

use super::SettingsError;
use crate::intake::ingest::{Area, IngestConfig};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Admission limits of the fuser node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct AdmissionSettings {
    /// Reject frames stamped further than this from the fuser's clock, ahead or behind (ms);
    /// 0 accepts any capture time (agents replaying data on its own clock, `v2x-agent --replay clock=data`).
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().max_clock_skew_ms))]
    pub max_clock_skew_ms: f64,
    /// Most agents tracked at once; beyond, the least recently heard agent without a liveliness
    /// token is forgotten to make room.
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().max_agents))]
    pub max_agents: usize,
    /// Forget an agent with no frame and no liveliness token for this long (s).
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().forget_after_s))]
    pub forget_after_s: f64,
    /// Closed windows that may wait for fusion; beyond, windows are dropped and counted.
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().fusion_queue))]
    pub fusion_queue: usize,
    /// Interval of the rate-limited warning summaries (s).
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().log_interval_s))]
    pub log_interval_s: f64,
    /// Most boxes one agent brings into a window; beyond, its lowest-scoring boxes are dropped
    /// and counted (`over_budget`), so no agent can crowd the others out of the fused frame.
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().max_objects_per_agent))]
    pub max_objects_per_agent: usize,
    /// The area of interest, X,Y,RADIUS in metres of the map frame: boxes outside it are
    /// dropped and counted (`outside`). Default: a disc of --area-radius-m around where most
    /// agents are, learned from their first boxes. (A scenario: `area = [X, Y, RADIUS]`.)
    #[cfg_attr(feature = "node", arg(long, value_name = "X,Y,RADIUS", value_parser = Area::parse, allow_hyphen_values = true))]
    #[serde(
        deserialize_with = "area_from_triple",
        serialize_with = "area_as_triple"
    )]
    pub area: Option<Area>,
    /// The radius of the learned area of interest (m), without --area.
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().area_radius_m, conflicts_with = "area"))]
    pub area_radius_m: f64,
}

impl Default for AdmissionSettings {
    fn default() -> Self {
        let i = IngestConfig::default();
        AdmissionSettings {
            max_clock_skew_ms: i.max_clock_skew_us.map_or(0.0, |us| us as f64 / 1000.0),
            max_agents: i.max_agents,
            forget_after_s: i.forget_after_us as f64 / 1e6,
            fusion_queue: 16,
            log_interval_s: 10.0,
            max_objects_per_agent: i.max_objects,
            area: None,
            area_radius_m: i.area.radius_m(),
        }
    }
}

/// A scenario's `area = [X, Y, RADIUS]`.
fn area_from_triple<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Area>, D::Error> {
    let [x, y, r] = <[f64; 3]>::deserialize(d)?;
    Ok(Some(Area::Given {
        center: [x, y],
        radius_m: r,
    }))
}

/// [`area_from_triple`] written back (a learned area: none).
fn area_as_triple<S: Serializer>(a: &Option<Area>, s: S) -> Result<S::Ok, S::Error> {
    match a {
        Some(Area::Given { center, radius_m }) => [center[0], center[1], *radius_m].serialize(s),
        _ => s.serialize_none(),
    }
}

impl AdmissionSettings {
    /// The admission limits, checked, into `ingest`.
    pub fn apply(&self, ingest: &mut IngestConfig) -> Result<(), SettingsError> {
        let bad = |key: &str, problem: &str| Err(SettingsError::of(key, problem));
        if !(self.max_clock_skew_ms >= 0.0 && self.max_clock_skew_ms.is_finite()) {
            return bad("max_clock_skew_ms", "must be >= 0 (0 turns the check off)");
        }
        if !(self.forget_after_s > 0.0 && self.forget_after_s.is_finite()) {
            return bad("forget_after_s", "must be > 0");
        }
        if !(self.log_interval_s > 0.0 && self.log_interval_s.is_finite()) {
            return bad("log_interval_s", "must be > 0");
        }
        for (n, key) in [
            (self.max_agents, "max_agents"),
            (self.fusion_queue, "fusion_queue"),
            (self.max_objects_per_agent, "max_objects_per_agent"),
        ] {
            if n == 0 {
                return bad(key, "must be at least 1");
            }
        }
        if self.max_agents > v2x_protocol::limits::MAX_WINDOW_AGENTS {
            return bad(
                "max_agents",
                &format!(
                    "may be at most {} (the most agents a fused frame can name)",
                    v2x_protocol::limits::MAX_WINDOW_AGENTS
                ),
            );
        }
        let area = self.area.unwrap_or(Area::Learned {
            radius_m: self.area_radius_m,
        });
        if let Err(e) = area.validate() {
            return bad(
                if self.area.is_some() {
                    "area"
                } else {
                    "area_radius_m"
                },
                &e.to_string(),
            );
        }
        ingest.max_clock_skew_us =
            (self.max_clock_skew_ms > 0.0).then_some((self.max_clock_skew_ms * 1000.0) as u64);
        ingest.max_agents = self.max_agents;
        ingest.max_objects = self.max_objects_per_agent;
        ingest.area = area;
        ingest.forget_after_us = (self.forget_after_s * 1e6) as u64;
        Ok(())
    }
}
