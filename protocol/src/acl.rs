//! Who may do what on which key: the Zenoh access-control policy of a namespace, built from the
//! key space in [`crate::keys`] so that the two cannot drift apart.
//!
//! Subjects are identified by the common name of their TLS client certificate. Everything not
//! allowed is denied:
//! - agent X may put only its detections (`v2x/NS/det/X`, or `v2x/NS/det/TILE/X` in any tile
//!   with regions), declare only its own liveliness token
//!   (`v2x/NS/alive/X`), see the fuser's subscription to its detections (so it knows a fuser is
//!   there), and ask the simulator's shared start (`v2x/NS/sim/epoch`);
//! - the fuser alone reads detections and tokens, and alone publishes fused output and tracks, declares its
//!   liveliness and answers the statistics and the shared start; regional fusers hold the same
//!   certificate name and rights, on their tiles' keys (`fused/TILE`, `fuser/TILE/stats`, ...),
//!   and hear each other's tracks (`tracks/TILE`) to hand tracks over at tile borders;
//! - an observer may only subscribe to fused output and tracks, query the statistics and watch the fuser's
//!   liveliness.
//!
//! The policy holds only where a router enforces it between clients: in peer mode sessions talk
//! to each other directly and no router sees their traffic.

use crate::keys;
use serde_json::{json, Value};

/// The certificate common name of the fuser.
pub const FUSER: &str = "fuser";
/// The certificate common name of an observer.
pub const OBSERVER: &str = "observer";
/// The certificate common name of the router (its server certificate).
pub const ROUTER: &str = "router";

/// Names no agent may take, because certificates of other roles carry them.
pub fn reserved(name: &str) -> bool {
    [FUSER, OBSERVER, ROUTER].contains(&name)
}

fn rule(id: &str, flow: &str, messages: &[&str], key_exprs: &[&str]) -> Value {
    json!({
        "id": id,
        "permission": "allow",
        "flows": [flow],
        "messages": messages,
        "key_exprs": key_exprs,
    })
}

/// The `access_control` section of the router's Zenoh configuration for namespace `ns` and the
/// given agents.
pub fn access_control(ns: &str, agents: &[String]) -> Value {
    let mut rules = Vec::new();
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    let roles = agents
        .iter()
        .map(|a| (format!("agent-{a}"), a.as_str(), agent_rules(ns, a)))
        .chain([
            (FUSER.to_owned(), FUSER, fuser_rules(ns)),
            (OBSERVER.to_owned(), OBSERVER, observer_rules(ns)),
        ]);
    for (id, common_name, rs) in roles {
        subjects.push(json!({"id": id, "cert_common_names": [common_name]}));
        policies.push(json!({
            "id": id,
            "subjects": [id],
            "rules": rs.iter().map(|r| r["id"].clone()).collect::<Vec<_>>(),
        }));
        rules.extend(rs);
    }
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    })
}

/// An agent's rules: it puts on its own detection keys, holds its own liveliness token, sees the
/// fuser's subscription to every agent, and asks for and answers the run's shared start.
fn agent_rules(ns: &str, a: &str) -> Vec<Value> {
    let id = format!("agent-{a}");
    let (det, tiled) = (keys::all_detections(ns), keys::all_tiled_detections(ns));
    let epoch_key = keys::sim_epoch(ns);
    let epoch = [epoch_key.as_str()];
    vec![
        rule(
            &format!("{id}-in"),
            "ingress",
            &["put"],
            &[
                keys::detections(ns, a).as_str(),
                keys::agent_tiled_detections(ns, a).as_str(),
            ],
        ),
        rule(
            &format!("{id}-token"),
            "ingress",
            &["liveliness_token"],
            &[keys::alive(ns, a).as_str()],
        ),
        // The fuser subscribes to every agent's detections at once (`det/*`, or `det/TILE/*`
        // for a regional fuser): an agent sees that declaration, and so knows a fuser is there.
        rule(
            &format!("{id}-matching"),
            "egress",
            &["declare_subscriber"],
            &[det.as_str(), tiled.as_str()],
        ),
        rule(&format!("{id}-epoch-in"), "ingress", &["query"], &epoch),
        rule(
            &format!("{id}-epoch-out"),
            "egress",
            &["reply", "declare_queryable"],
            &epoch,
        ),
    ]
}

/// The keys as the rules take them.
fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// The keys of the fusers' output, statistics and liveliness, single and regional.
struct FuserSide {
    output: Vec<String>,
    /// The regional fusers' tracks, which their neighbours hear for the hand-over.
    regional_tracks: String,
    stats: Vec<String>,
    alive: Vec<String>,
}

impl FuserSide {
    fn of(ns: &str) -> Self {
        let (one, any) = (
            keys::FuserKeys::of(ns, None),
            keys::FuserKeys::any_region(ns),
        );
        FuserSide {
            output: vec![one.fused, any.fused, one.tracks, any.tracks.clone()],
            regional_tracks: any.tracks,
            stats: vec![one.stats, any.stats],
            alive: vec![one.alive, any.alive],
        }
    }
}

/// The fuser's rules: it subscribes to every agent's detections and liveliness, publishes its
/// output and liveliness, and answers statistics and the run's shared start.
fn fuser_rules(ns: &str) -> Vec<Value> {
    let (det, tiled) = (keys::all_detections(ns), keys::all_tiled_detections(ns));
    let alive = keys::all_alive(ns);
    let f = FuserSide::of(ns);
    let dets = [det.as_str(), tiled.as_str()];
    let output = strs(&f.output);
    let epoch_key = keys::sim_epoch(ns);
    let asked = [strs(&f.stats), vec![epoch_key.as_str()]].concat();
    vec![
        rule("fuser-subscribe", "ingress", &["declare_subscriber"], &dets),
        rule("fuser-detections", "egress", &["put"], &dets),
        rule(
            "fuser-tokens-subscribe",
            "ingress",
            &["declare_liveliness_subscriber", "liveliness_query"],
            &[alive.as_str()],
        ),
        rule(
            "fuser-tokens",
            "egress",
            &["liveliness_token", "reply"],
            &[alive.as_str()],
        ),
        rule("fuser-publish", "ingress", &["put"], &output),
        // A regional fuser hears its neighbours' tracks, to hand tracks over at tile borders.
        rule(
            "fuser-handover",
            "ingress",
            &["declare_subscriber"],
            &[f.regional_tracks.as_str()],
        ),
        rule(
            "fuser-handover-tracks",
            "egress",
            &["put"],
            &[f.regional_tracks.as_str()],
        ),
        // Observers' subscriptions reach the fuser, which then sends its output.
        rule("fuser-readers", "egress", &["declare_subscriber"], &output),
        rule(
            "fuser-alive",
            "ingress",
            &["liveliness_token"],
            &strs(&f.alive),
        ),
        rule(
            "fuser-answer",
            "ingress",
            &["declare_queryable", "reply"],
            &asked,
        ),
        rule("fuser-questions", "egress", &["query"], &asked),
    ]
}

/// An observer's rules: it subscribes to the fusers' output and asks for their statistics and
/// liveliness.
fn observer_rules(ns: &str) -> Vec<Value> {
    let f = FuserSide::of(ns);
    let output = strs(&f.output);
    let watched = [strs(&f.stats), strs(&f.alive)].concat();
    vec![
        rule(
            "observer-subscribe",
            "ingress",
            &["declare_subscriber"],
            &output,
        ),
        rule("observer-fused", "egress", &["put"], &output),
        rule(
            "observer-ask",
            "ingress",
            &["query", "declare_liveliness_subscriber", "liveliness_query"],
            &watched,
        ),
        rule(
            "observer-answers",
            "egress",
            &["reply", "liveliness_token", "declare_queryable"],
            &watched,
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn allowed(acl: &Value, subject: &str, flow: &str, message: &str) -> Vec<String> {
        let policy = acl["policies"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["subjects"][0] == subject)
            .unwrap();
        let mut keys = Vec::new();
        for id in policy["rules"].as_array().unwrap() {
            let r = acl["rules"]
                .as_array()
                .unwrap()
                .iter()
                .find(|r| r["id"] == *id)
                .unwrap();
            let has = |f: &str, v: &str| r[f].as_array().unwrap().iter().any(|x| x == v);
            if has("flows", flow) && has("messages", message) {
                keys.extend(
                    r["key_exprs"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|k| k.as_str().unwrap().to_string()),
                );
            }
        }
        keys
    }

    #[test]
    fn each_agent_writes_only_its_own_keys() {
        let acl = access_control("ns", &["veh".into(), "rsu".into()]);
        assert_eq!(acl["default_permission"], "deny");
        assert_eq!(
            allowed(&acl, "agent-veh", "ingress", "put"),
            vec!["v2x/ns/det/veh", "v2x/ns/det/*/veh"]
        );
        assert_eq!(
            allowed(&acl, "agent-veh", "ingress", "liveliness_token"),
            vec!["v2x/ns/alive/veh"]
        );
        assert!(
            allowed(&acl, "agent-veh", "egress", "put").is_empty(),
            "reads nothing"
        );
        assert!(allowed(&acl, "agent-rsu", "ingress", "declare_queryable").is_empty());
        assert_eq!(
            allowed(&acl, "fuser", "ingress", "put"),
            vec![
                "v2x/ns/fused",
                "v2x/ns/fused/*",
                "v2x/ns/tracks",
                "v2x/ns/tracks/*"
            ]
        );
        assert_eq!(
            allowed(&acl, "fuser", "egress", "put"),
            vec!["v2x/ns/det/*", "v2x/ns/det/*/*", "v2x/ns/tracks/*"]
        );
        assert_eq!(
            allowed(&acl, "fuser", "ingress", "declare_subscriber"),
            vec!["v2x/ns/det/*", "v2x/ns/det/*/*", "v2x/ns/tracks/*"]
        );
        assert!(allowed(&acl, "observer", "ingress", "put").is_empty());
        assert_eq!(
            allowed(&acl, "observer", "egress", "put"),
            vec![
                "v2x/ns/fused",
                "v2x/ns/fused/*",
                "v2x/ns/tracks",
                "v2x/ns/tracks/*"
            ]
        );
        assert!(reserved("fuser") && !reserved("veh"));
        let subjects = acl["subjects"].as_array().unwrap();
        assert_eq!(subjects[0]["cert_common_names"][0], "veh");
    }
}
