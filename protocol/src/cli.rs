//! Command-line options that commands of several binaries share and that are not Zenoh's, each
//! declared once, and how every binary ends when its standard output is closed.

use std::path::PathBuf;

/// Where a command writes (`-o/--output`; `--out` as well).
#[derive(clap::Args, Clone, Debug)]
pub struct Output {
    /// Where to write: the file or folder the command's description names.
    #[arg(
        short = 'o',
        long = "output",
        visible_alias = "out",
        value_name = "PATH"
    )]
    pub path: PathBuf,
}

/// Which clock stamps a replay's capture times.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReplayClock {
    /// The data's time mapped onto this machine's clock from `start_at`.
    #[default]
    Real,
    /// The data's own timestamps.
    Data,
}

/// How recorded data is replayed (`--replay KEY=VALUE,...`): the agent's playback, and what
/// `v2x-sim eval` needs to map a recording of it back to the data's time.
#[derive(Copy, Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Replay {
    /// Playback speed factor (2 = twice as fast), > 0.
    pub speed: f64,
    /// With the real clock: when the first frame is captured, in Unix seconds (none: now).
    pub start_at: Option<f64>,
    /// Which clock stamps capture times.
    pub clock: ReplayClock,
    /// Frame rate of samples whose times are not known (Hz), > 0.
    pub hz: f64,
}

impl Default for Replay {
    fn default() -> Self {
        Replay {
            speed: 1.0,
            start_at: None,
            clock: ReplayClock::Real,
            hz: 10.0,
        }
    }
}

impl Replay {
    /// Checks the values are usable, naming the bad key.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.speed > 0.0 && self.speed.is_finite()) {
            return Err(format!("speed: expected > 0, got {}", self.speed));
        }
        if !(self.hz > 0.0 && self.hz.is_finite()) {
            return Err(format!("hz: expected > 0, got {}", self.hz));
        }
        match (self.clock, self.start_at) {
            (ReplayClock::Data, Some(_)) => Err("start_at goes with clock=real".into()),
            (_, Some(t)) if !(t > 0.0 && t.is_finite()) => {
                Err(format!("start_at: expected a positive Unix time, got {t}"))
            }
            _ => Ok(()),
        }
    }
}

/// `--replay KEY=VALUE,...`, read and checked.
pub fn parse_replay(s: &str) -> Result<Replay, String> {
    let r: Replay = crate::pairs::from_pairs(s)?;
    r.validate()?;
    Ok(r)
}

/// The replay of recorded data on the command line (`--replay`), declared once for the agent
/// that replays and the evaluation that maps its recording back.
#[derive(clap::Args, Clone, Copy, Debug)]
pub struct ReplayArg {
    /// How the data is replayed, KEY=VALUE,...: speed (the playback speed factor, 1), clock
    /// (`real`: the data's time mapped onto this machine's clock from start_at, what a fuser
    /// with its default clock tolerance expects; `data`: the data's own timestamps, for
    /// `v2x-fuser node --max-clock-skew-ms 0`), start_at (with the real clock, the first
    /// capture's Unix time; default now: give several agents the same and they replay in step)
    /// and hz (the frame rate of samples without known times, 10). `v2x-sim eval` takes the
    /// agents' value to map a recording back to the data. E.g. speed=2,start_at=1767225600.
    #[arg(long, value_name = "KEY=VALUE,...", default_value = "", hide_default_value = true, value_parser = parse_replay, allow_hyphen_values = true)]
    pub replay: Replay,
}

/// Ends the program quietly when its standard output is closed (`... | head`), as Unix tools
/// do, instead of with a panic from `println!`; the exit status is a broken pipe's (141).
pub fn quiet_on_closed_stdout() {
    let report = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to stdout") && message.contains("Broken pipe") {
            std::process::exit(141);
        }
        report(info)
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_replay_reads_its_keys_and_names_a_bad_one() {
        let r = parse_replay("speed=2,start_at=1767225600").unwrap();
        assert_eq!(
            (r.speed, r.start_at, r.clock, r.hz),
            (2.0, Some(1767225600.0), ReplayClock::Real, 10.0)
        );
        assert_eq!(parse_replay("").unwrap(), Replay::default());
        assert_eq!(
            parse_replay("clock=data,hz=2").unwrap().clock,
            ReplayClock::Data
        );
        assert!(parse_replay("speed=0").unwrap_err().starts_with("speed:"));
        assert!(parse_replay("hz=-1").unwrap_err().starts_with("hz:"));
        assert!(parse_replay("clock=data,start_at=5")
            .unwrap_err()
            .contains("clock=real"));
        assert!(parse_replay("start_at=-3")
            .unwrap_err()
            .starts_with("start_at:"));
        assert!(parse_replay("sped=2").unwrap_err().contains("sped"));
    }
}
