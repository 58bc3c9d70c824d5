use super::*;
use serde_json::json;

/// The payload counters of the admin space: `{ "admin": n, "user": n }` per message kind.
fn payload(tx_puts: u64, tx_bytes: u64, rx_puts: u64, rx_bytes: u64) -> Value {
    let space = |n: u64| json!({ "admin": 7, "user": n });
    let mut m = serde_json::Map::new();
    for (d, puts, bytes) in [("tx", tx_puts, tx_bytes), ("rx", rx_puts, rx_bytes)] {
        m.insert(format!("{d}_z_put_msgs"), space(puts));
        m.insert(format!("{d}_z_put_pl_bytes"), space(bytes));
        for kind in ["del", "query", "reply"] {
            m.insert(format!("{d}_z_{kind}_msgs"), space(0));
            m.insert(format!("{d}_z_{kind}_pl_bytes"), space(0));
        }
    }
    Value::Object(m)
}

fn transport(tx_bytes: u64, rx_bytes: u64, payload_stats: Value) -> Value {
    let mut m = payload_stats.as_object().unwrap().clone();
    for (d, b) in [("tx", tx_bytes), ("rx", rx_bytes)] {
        m.insert(format!("{d}_bytes"), json!(b));
        m.insert(format!("{d}_t_msgs"), json!(b / 100));
        m.insert(format!("{d}_n_msgs"), json!({ "net": b / 50, "shm": 1 }));
        m.insert(format!("{d}_n_dropped"), json!(0));
    }
    Value::Object(m)
}

/// A fuser's view: agent a over one transport, agent b over another.
fn sample() -> Value {
    let keys = |a: Value, b: Value| {
        json!([
            { "key": "v2x/ns/det/a", "stats": a },
            { "key": "v2x/ns/det/b", "stats": b },
        ])
    };
    json!({
        "zid": "f1",
        "stats": transport(900, 12_000, payload(0, 0, 30, 9_000)),
        "stats_filtered": keys(payload(0, 0, 10, 4_000), payload(0, 0, 20, 5_000)),
        "sessions": [
            {
                "peer": "a1", "whatami": "peer", "links": [],
                "stats": transport(400, 5_000, payload(0, 0, 10, 4_000)),
                "stats_filtered": keys(payload(0, 0, 10, 4_000), payload(0, 0, 0, 0)),
            },
            {
                "peer": "b1", "whatami": "client", "links": [],
                "stats": transport(500, 7_000, payload(0, 0, 20, 5_000)),
                "stats_filtered": keys(payload(0, 0, 0, 0), payload(0, 0, 20, 5_000)),
            },
        ],
    })
}

#[test]
fn the_admin_space_reply_is_read_field_by_field() {
    let t = Traffic::parse(sample().to_string().as_bytes()).unwrap();
    assert_eq!(
        t.total.rx,
        Counters {
            bytes: 12_000,
            transport_msgs: 120,
            network_msgs: 241,
            put_msgs: 30,
            put_payload_bytes: 9_000,
        }
    );
    assert_eq!(t.total.tx.bytes, 900);
    assert_eq!(t.key("v2x/ns/det/b").rx.put_payload_bytes, 5_000);
    assert_eq!(t.key("v2x/ns/det/b").rx.bytes, 0, "keys count puts only");
    assert_eq!(t.key("v2x/ns/other"), Flow::default());
    assert_eq!(t.peers.len(), 2);
    assert_eq!(t.peers[1].whatami, "client");
    assert_eq!(t.sole_sender("v2x/ns/det/a").unwrap().zid, "a1");
    assert_eq!(t.sole_sender("v2x/ns/det/b").unwrap().total.rx.bytes, 7_000);
    assert!(t.sole_sender("v2x/ns/det/c").is_none());
    assert_eq!(
        t.sent_with("v2x/ns/det/a"),
        Counters::default(),
        "nothing sent on it"
    );
}

#[test]
fn a_publisher_s_traffic_is_what_went_to_its_subscribers() {
    // An agent: its detections went to the fuser (f1); it also talks to another agent (b1).
    let mut v = sample();
    let keys = |a: Value| json!([{ "key": "v2x/ns/det/a", "stats": a }]);
    v["sessions"] = json!([
        {
            "peer": "f1", "whatami": "peer", "links": [],
            "stats": transport(5_000, 300, payload(10, 4_000, 0, 0)),
            "stats_filtered": keys(payload(10, 4_000, 0, 0)),
        },
        {
            "peer": "b1", "whatami": "peer", "links": [],
            "stats": transport(200, 200, payload(0, 0, 0, 0)),
            "stats_filtered": keys(payload(0, 0, 0, 0)),
        },
    ]);
    let t = Traffic::parse(v.to_string().as_bytes()).unwrap();
    let c = t.sent_with("v2x/ns/det/a");
    assert_eq!(
        (c.bytes, c.put_msgs, c.put_payload_bytes),
        (5_000, 10, 4_000)
    );
    assert_eq!(c.overhead_per_put(), Some(100.0));
}

#[test]
fn one_transport_carrying_two_senders_is_nobody_s_alone() {
    // Through a router, both agents' puts come over one transport.
    let mut v = sample();
    v["sessions"] = json!([{
        "peer": "r1", "whatami": "router", "links": [],
        "stats": transport(900, 12_000, payload(0, 0, 30, 9_000)),
        "stats_filtered": v["stats_filtered"].clone(),
    }]);
    let t = Traffic::parse(v.to_string().as_bytes()).unwrap();
    assert!(t.sole_sender("v2x/ns/det/a").is_none());
    assert!(t.sole_sender("v2x/ns/det/b").is_none());
    assert_eq!(t.key("v2x/ns/det/a").rx.put_msgs, 10);
}

#[test]
fn overhead_and_differences() {
    let later = Counters {
        bytes: 5_000,
        transport_msgs: 12,
        network_msgs: 14,
        put_msgs: 10,
        put_payload_bytes: 4_000,
    };
    assert_eq!(later.overhead_per_put(), Some(100.0));
    assert_eq!(Counters::default().overhead_per_put(), None);
    let earlier = Counters {
        bytes: 1_000,
        put_msgs: 2,
        put_payload_bytes: 800,
        ..Default::default()
    };
    let d = later.since(&earlier);
    assert_eq!(
        (d.bytes, d.put_msgs, d.put_payload_bytes),
        (4_000, 8, 3_200)
    );
    assert_eq!(earlier.since(&later).bytes, 0, "saturates");
}

#[test]
fn malformed_replies_name_the_field() {
    let mut v = sample();
    v["sessions"][1]["stats"]["rx_bytes"] = json!(-3);
    let e = Traffic::parse(v.to_string().as_bytes()).unwrap_err();
    assert_eq!(e.to_string(), "sessions[1].stats.rx_bytes: not a count");
    assert_eq!(
        e,
        TrafficError::Field {
            path: "sessions[1].stats.rx_bytes".into(),
            problem: Problem::NotCount
        }
    );
    let mut v = sample();
    v["stats"]["tx_z_put_msgs"] = json!({ "admin": 1 });
    let e = Traffic::parse(v.to_string().as_bytes()).unwrap_err();
    assert_eq!(e.to_string(), "stats.tx_z_put_msgs.user: missing");
    let mut v = sample();
    v["stats_filtered"][0]["key"] = json!(3);
    let e = Traffic::parse(v.to_string().as_bytes()).unwrap_err();
    assert_eq!(e.to_string(), "stats_filtered[0].key: not a string");
    let mut v = sample();
    v["sessions"][0]["stats_filtered"][0]["stats"] = json!({});
    let e = Traffic::parse(v.to_string().as_bytes()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "sessions[0].stats_filtered[0].stats.tx_z_put_msgs: missing"
    );
    let e = Traffic::parse(b"{").unwrap_err();
    assert!(matches!(e, TrafficError::NotJson(_)), "{e}");
    let mut v = sample();
    v.as_object_mut().unwrap().remove("sessions");
    assert_eq!(
        Traffic::parse(v.to_string().as_bytes())
            .unwrap_err()
            .to_string(),
        "sessions: missing"
    );
}

#[test]
fn the_configuration_pairs_enable_the_statistics_per_key() {
    let p = stats_pairs(&["v2x/ns/det/a".into()]);
    assert!(p.contains(&("adminspace/enabled", "true".into())));
    assert!(p.contains(&("stats/filters", r#"[{"key":"v2x/ns/det/a"}]"#.into())));
}
