//! What the command line adds to the fuser's settings (`v2x_fuser::settings`): errors by flag,
//! the learned stds' report and the region a node serves.

use v2x_fuser::settings::SettingsError;

/// A setting's error, by its flag.
pub(crate) fn flag_error(e: SettingsError) -> anyhow::Error {
    anyhow::anyhow!(e.on_command_line())
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
    #[command(flatten)]
    pub(crate) tiles: v2x_protocol::tiles::TileSize,
    #[command(flatten)]
    pub(crate) halo: v2x_protocol::tiles::Halo,
}

impl RegionArgs {
    pub(crate) fn region(&self) -> anyhow::Result<Option<v2x_fuser::intake::region::Region>> {
        let Some(tile) = self.tile else {
            if self.tiles.tiling.is_some() || self.halo.halo.is_some() {
                anyhow::bail!("--tile-size and --halo shape a regional fuser: give --tile too");
            }
            return Ok(None);
        };
        Ok(Some(v2x_fuser::intake::region::Region {
            tiling: self.tiles.tiling_or_default(),
            tile,
            halo_m: self.halo.halo_m(),
        }))
    }
}
