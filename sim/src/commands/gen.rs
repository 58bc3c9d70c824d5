//! `v2x-sim gen`.

use anyhow::Context;
use v2x_protocol::nuscenes_json::write_results;
use v2x_sim::cli::DataArgs;
use v2x_sim::noise::NoiseSetting;

/// The options of `v2x-sim gen`.
#[derive(clap::Args)]
pub struct GenArgs {
    #[command(flatten)]
    pub data: DataArgs,
    /// Noise: mild, moderate, large, realistic, a mix such as mild+large (one per agent), or
    /// POS,SIZE,YAW_DEG, or labels (each object exactly as labelled, stating 0.5 m, 0.2 m and
    /// 0.1 rad) [default: mild+large; with --dataset dair-v2x: labels, each side's own; with
    /// --dataset v2v4real none applies: the cars' own detections are written].
    #[arg(long)]
    pub noise: Option<String>,
    /// Detector faults, replacing the noise profile's own (none, except for `realistic`):
    /// `none`, `realistic`, or KEY=VALUE,... (keys below); one for all agents or one per
    /// agent joined by '+'.
    #[arg(long)]
    pub faults: Option<String>,
    /// The stds each agent states with its boxes, replacing its noise's own: `honest` (the
    /// default), `xK` (the noise's stds times K: x6 six times too wide, x0.17 six times too
    /// narrow), a profile or POS,SIZE,YAW_DEG (e.g. `mild` for a large-noise agent: an
    /// overconfident detector), or `none` (no std fields in its file); one for all agents or
    /// one per agent joined by '+'.
    #[arg(long)]
    pub stated_std: Option<String>,
    /// Number of agents.
    #[arg(long, default_value_t = 2)]
    pub agents: usize,
    #[command(flatten)]
    pub draw: v2x_sim::cli::DrawArgs,
    /// Capture rate of each agent in Hz, comma-separated, or one for all (default: the
    /// data's rate, on its frames).
    #[arg(long)]
    pub agent_hz: Option<String>,
    /// Phase of each agent in ms after each scene's first frame, comma-separated, or one
    /// for all (default 0).
    #[arg(long)]
    pub phase_ms: Option<String>,
    #[command(flatten)]
    pub out: v2x_protocol::cli::Output,
}

/// A noise setting for `agents` agents with the faults and stated stds given, if any.
pub(crate) fn setting_with_faults(
    noise: &str,
    faults: Option<&str>,
    stated: Option<&str>,
    agents: usize,
) -> anyhow::Result<NoiseSetting> {
    let mut setting = NoiseSetting::parse(noise, agents).map_err(anyhow::Error::msg)?;
    if let Some(f) = faults {
        setting
            .set_faults(f)
            .map_err(|e| anyhow::anyhow!("--faults: {e}"))?;
    }
    if let Some(s) = stated {
        setting
            .set_stated(s)
            .map_err(|e| anyhow::anyhow!("--stated-std: {e}"))?;
    }
    Ok(setting)
}

/// Writes one agent's results file, without std fields when the agent states none.
pub(crate) fn write_agent(
    path: &std::path::Path,
    r: &v2x_protocol::nuscenes_json::Results,
    tokens: &v2x_protocol::nuscenes_json::TokenTable,
    noise: &v2x_sim::noise::AgentNoise,
) -> anyhow::Result<()> {
    if noise.stated != v2x_truth::stated::Stated::Nothing {
        return Ok(write_results(path, r, tokens)?);
    }
    let mut doc = v2x_protocol::nuscenes_json::results_json(r, tokens);
    for b in doc["results"]
        .as_object_mut()
        .into_iter()
        .flat_map(|m| m.values_mut())
        .filter_map(|v| v.as_array_mut())
        .flatten()
        .filter_map(|b| b.as_object_mut())
    {
        for k in ["translation_std", "size_std", "yaw_std", "velocity_std"] {
            b.remove(k);
        }
    }
    std::fs::write(path, serde_json::to_string(&doc)?)
        .with_context(|| format!("cannot write {}", path.display()))
}
