//! What the command line adds to the fuser's settings (`v2x_fuser::settings`): the region a
//! node serves, and how `fuse` and `track` name their inputs' models and read missing stds.

use v2x_fuser::settings::{SettingsError, StdSettings};
use v2x_protocol::nuscenes_json::MissingStd;

/// A setting's error, by its flag.
pub(crate) fn flag_error(e: SettingsError) -> anyhow::Error {
    anyhow::anyhow!(e.on_command_line())
}

/// The models by input position, for files: AGENT must be agentN with 1 <= N <= `inputs`.
pub(crate) fn models_by_input(
    stds: &StdSettings,
    inputs: usize,
) -> anyhow::Result<std::collections::BTreeMap<usize, v2x_fuser::uncertainty::stdmodel::ErrorModel>>
{
    stds.models()
        .map_err(flag_error)?
        .0
        .into_iter()
        .map(|(agent, m)| {
            let n = agent
                .strip_prefix("agent")
                .and_then(|n| n.parse::<usize>().ok())
                .filter(|n| (1..=inputs).contains(n))
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "--std-model {agent}: name the input as agentN, N from 1 to {inputs} (its position)"
                    )
                })?;
            Ok((n - 1, m))
        })
        .collect()
}

/// What to do with a box that states no std: the default given, else the learner's prior when
/// learning or when every one of the `inputs` has a model (which replaces the stds), else an
/// error.
pub(crate) fn missing(
    stds: &StdSettings,
    default_std: Option<v2x_protocol::Uncertainty>,
    inputs: usize,
) -> MissingStd {
    let replaced = stds.learn_std || (inputs > 0 && stds.std_models.len() >= inputs);
    match (default_std, replaced) {
        (Some(u), _) => MissingStd::Default(u),
        (None, true) => {
            MissingStd::Default(v2x_fuser::uncertainty::learn::LearnParams::default().prior)
        }
        (None, false) => MissingStd::Error,
    }
}

/// Prints what was learned of each agent's stds.
pub(crate) fn print_learned(
    learned: &std::collections::BTreeMap<String, v2x_fuser::uncertainty::learn::AgentReport>,
) {
    for (agent, r) in learned {
        match &r.all.pos_xy {
            Some(g) => eprintln!(
                "learned stds of {agent}: centre {:.2} m where it states {:.2} m (x{:.2}{}) from {} residuals; per class in meta.v2x_learned_std",
                g.estimated,
                g.stated,
                g.ratio,
                if r.flagged { ", flagged: its stated stds are inconsistent" } else { "" },
                g.samples
            ),
            None => eprintln!("learned stds of {agent}: too few boxes followed over three frames"),
        }
    }
}

/// The region a fuser node serves.
#[derive(clap::Args)]
pub(crate) struct RegionArgs {
    /// Serve one tile as a regional fuser (COLUMN_ROW, e.g. 0_0 or -1_2): subscribe to
    /// v2x/NS/det/TILE/* for it and its halo, publish on v2x/NS/fused/TILE the fused boxes whose
    /// centre lies in it. Agents must publish per tile (`v2x-agent --tile-size`, same size).
    #[arg(long)]
    pub(crate) tile: Option<v2x_protocol::tiles::Tile>,
    /// Side of the map's square tiles (m), as the agents use.
    #[arg(long, default_value_t = v2x_fuser::intake::region::DEFAULT_TILE_M, requires = "tile")]
    pub(crate) tile_size: f64,
    /// How far beyond its tile a regional fuser takes boxes (m): at least the association's
    /// reach, so groups across the border are fused as one fuser would.
    #[arg(long, default_value_t = v2x_fuser::intake::region::DEFAULT_HALO_M, requires = "tile")]
    pub(crate) halo: f64,
}

impl RegionArgs {
    pub(crate) fn region(&self) -> anyhow::Result<Option<v2x_fuser::intake::region::Region>> {
        let Some(tile) = self.tile else {
            return Ok(None);
        };
        let tiling = v2x_protocol::tiles::Tiling::new(self.tile_size)
            .map_err(|e| anyhow::anyhow!("--tile-size: {e}"))?;
        if !(self.halo >= 0.0 && self.halo.is_finite()) {
            anyhow::bail!("--halo must be >= 0 m");
        }
        Ok(Some(v2x_fuser::intake::region::Region {
            tiling,
            tile,
            halo_m: self.halo,
        }))
    }
}
