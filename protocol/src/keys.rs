//! Zenoh key expressions, built and parsed in one place (specified in `docs/wire-format.md`).
//!
//! Everything lives under `v2x/NS/…`, `NS` being the scenario namespace:
//! `det/AGENT` (detections), `fused` (fused frames), `tracks` (tracked boxes, each box's id its
//! track), `alive/AGENT` (liveliness) and
//! `fuser/stats` (the fuser's statistics queryable).

/// Root of every key.
pub const ROOT: &str = "v2x";

/// Checks that a namespace or agent name is a single, non-empty key chunk without wildcards.
pub fn validate_chunk(what: &str, s: &str) -> Result<(), String> {
    if s.is_empty() {
        return Err(format!("{what} must not be empty"));
    }
    if let Some(c) = s
        .chars()
        .find(|c| matches!(c, '/' | '*' | '$' | '?' | '#') || c.is_whitespace())
    {
        return Err(format!(
            "{what} '{s}' contains '{c}'; use letters, digits, '-', '_' or '.'"
        ));
    }
    Ok(())
}

/// Detections of one agent: `v2x/NS/det/AGENT`.
pub fn detections(ns: &str, agent: &str) -> String {
    format!("{ROOT}/{ns}/det/{agent}")
}

/// Detections of every agent: `v2x/NS/det/*`.
pub fn all_detections(ns: &str) -> String {
    format!("{ROOT}/{ns}/det/*")
}

/// Fused frames: `v2x/NS/fused`.
pub fn fused(ns: &str) -> String {
    format!("{ROOT}/{ns}/fused")
}

/// Tracks: `v2x/NS/tracks`.
pub fn tracks(ns: &str) -> String {
    format!("{ROOT}/{ns}/tracks")
}

/// Liveliness token of one agent: `v2x/NS/alive/AGENT`.
pub fn alive(ns: &str, agent: &str) -> String {
    format!("{ROOT}/{ns}/alive/{agent}")
}

/// Liveliness tokens of every agent: `v2x/NS/alive/*`.
pub fn all_alive(ns: &str) -> String {
    format!("{ROOT}/{ns}/alive/*")
}

/// The fuser's statistics queryable: `v2x/NS/fuser/stats`.
pub fn fuser_stats(ns: &str) -> String {
    format!("{ROOT}/{ns}/fuser/stats")
}

/// Liveliness token of the fuser: `v2x/NS/fuser/alive`.
pub fn fuser_alive(ns: &str) -> String {
    format!("{ROOT}/{ns}/fuser/alive")
}

/// The agent name of a `v2x/NS/det/AGENT` key, if the key is one.
pub fn agent_of_detections(ns: &str, key: &str) -> Option<String> {
    suffix_after(key, &format!("{ROOT}/{ns}/det/"))
}

/// The agent name of a `v2x/NS/alive/AGENT` key, if the key is one.
pub fn agent_of_alive(ns: &str, key: &str) -> Option<String> {
    suffix_after(key, &format!("{ROOT}/{ns}/alive/"))
}

fn suffix_after(key: &str, prefix: &str) -> Option<String> {
    let rest = key.strip_prefix(prefix)?;
    (!rest.is_empty() && !rest.contains('/')).then(|| rest.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn build_and_parse() {
        assert_eq!(detections("s1", "veh"), "v2x/s1/det/veh");
        assert_eq!(
            agent_of_detections("s1", "v2x/s1/det/veh").as_deref(),
            Some("veh")
        );
        assert_eq!(agent_of_detections("s1", "v2x/s2/det/veh"), None);
        assert_eq!(agent_of_detections("s1", "v2x/s1/det/a/b"), None);
        assert_eq!(
            agent_of_alive("s1", &alive("s1", "rsu")).as_deref(),
            Some("rsu")
        );
        assert_eq!(fused("x"), "v2x/x/fused");
        assert_eq!(tracks("x"), "v2x/x/tracks");
        assert_eq!(fuser_stats("x"), "v2x/x/fuser/stats");
        assert!(validate_chunk("agent", "veh-1").is_ok());
        assert!(validate_chunk("agent", "a/b").is_err());
        assert!(validate_chunk("agent", "").is_err());
        assert!(validate_chunk("agent", "a*").is_err());
    }
}
