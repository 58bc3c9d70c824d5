//! Rate-limited log lines, sans-IO: the first event of a reason in an interval is told at once
//! with its detail; the rest are counted and summed up in one line per reason when the interval
//! ends. A flood of bad frames thus costs a few lines a minute, not one line a frame.

use std::collections::BTreeMap;

#[derive(Debug, Default)]
struct Tally {
    told: u64,
    suppressed: u64,
}

/// Per-reason log limiter.
#[derive(Debug)]
pub struct RateLog {
    interval_us: u64,
    started_us: u64,
    tallies: BTreeMap<&'static str, Tally>,
}

impl RateLog {
    /// One line per reason per `interval_us` (plus the summary), starting at `now_us`.
    pub fn new(interval_us: u64, now_us: u64) -> Self {
        RateLog {
            interval_us: interval_us.max(1),
            started_us: now_us,
            tallies: BTreeMap::new(),
        }
    }

    /// Notes an event; returns the line to log now, if any.
    pub fn note(&mut self, reason: &'static str, detail: &str) -> Option<String> {
        self.note_up_to(reason, detail, 1)
            .map(|line| format!("{reason}: {line}"))
    }

    /// Notes an event of which the first `n` in an interval are told as they are (the line
    /// is `detail` itself); returns the line to log now, if any.
    pub fn note_up_to(&mut self, reason: &'static str, detail: &str, n: u64) -> Option<String> {
        let t = self.tallies.entry(reason).or_default();
        if t.told >= n {
            t.suppressed += 1;
            None
        } else {
            t.told += 1;
            Some(detail.to_string())
        }
    }

    /// When the interval has ended, the summary lines of what was suppressed in it (and a new
    /// interval starts); otherwise nothing.
    pub fn tick(&mut self, now_us: u64) -> Vec<String> {
        if now_us.saturating_sub(self.started_us) < self.interval_us {
            return Vec::new();
        }
        self.flush(now_us)
    }

    /// The summary lines of the interval so far, whether or not it has ended (at shutdown).
    pub fn flush(&mut self, now_us: u64) -> Vec<String> {
        let secs = now_us.saturating_sub(self.started_us) as f64 / 1e6;
        self.started_us = now_us;
        std::mem::take(&mut self.tallies)
            .into_iter()
            .filter(|(_, t)| t.suppressed > 0)
            .map(|(r, t)| format!("{r}: {} more in the last {secs:.0} s", t.suppressed))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_costs_one_line_and_a_summary() {
        let mut log = RateLog::new(10_000_000, 0);
        assert_eq!(
            log.note("invalid", "object 3: bad tag").as_deref(),
            Some("invalid: object 3: bad tag")
        );
        for _ in 0..999 {
            assert!(log.note("invalid", "again").is_none());
        }
        assert!(log.note("future", "1 h ahead").is_some());
        assert!(log.tick(9_999_999).is_empty());
        assert_eq!(
            log.tick(10_000_000),
            vec!["invalid: 999 more in the last 10 s".to_string()]
        );
        // a new interval: the next event is told again
        assert!(log.note("invalid", "x").is_some());
        assert!(log.tick(15_000_000).is_empty());
    }

    #[test]
    fn the_first_n_are_told_as_they_are() {
        let mut log = RateLog::new(10_000_000, 0);
        let told: Vec<_> = (0..400)
            .filter_map(|k| log.note_up_to("agents", &format!("agent a{k} is live"), 16))
            .collect();
        assert_eq!(told.len(), 16);
        assert_eq!(told[15], "agent a15 is live");
        assert_eq!(
            log.tick(10_000_000),
            vec!["agents: 384 more in the last 10 s".to_string()]
        );
    }
}
