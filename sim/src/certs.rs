//! `v2x-sim certs`: everything a secure deployment needs, so that nobody writes certificates or
//! ACL JSON by hand. It makes a certificate authority, one client certificate per agent (common
//! name = the agent's name), one for the fuser and one for an observer, a server certificate for
//! the router, and the Zenoh configuration files of each role: the router's with mutual TLS and
//! the access-control policy of [`v2x_protocol::acl`], and client configurations that connect
//! to the router over mutual TLS with multicast scouting off.

use anyhow::{bail, Context};
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use time::{Duration, OffsetDateTime};
use v2x_protocol::{acl, keys, limits, wire};

/// What to issue.
#[derive(Clone, Debug)]
pub struct CertsConfig {
    /// Output directory (created).
    pub out: PathBuf,
    /// Namespace the access-control policy covers.
    pub ns: String,
    /// Agent names, one certificate each.
    pub agents: Vec<String>,
    /// Endpoints the router listens on (`tls/...`).
    pub listen: Vec<String>,
    /// Endpoints the clients connect to (`tls/HOST:PORT`); their hosts go into the router's
    /// certificate, with `localhost` and `127.0.0.1`.
    pub connect: Vec<String>,
    /// Days the certificates are valid.
    pub days: u32,
}

/// The files written.
#[derive(Clone, Debug)]
pub struct Issued {
    /// The output directory, absolute.
    pub dir: PathBuf,
    /// The CA certificate.
    pub ca: PathBuf,
    /// Zenoh configuration of the router.
    pub router: PathBuf,
    /// Zenoh configuration of the fuser.
    pub fuser: PathBuf,
    /// Zenoh configuration of an observer.
    pub observer: PathBuf,
    /// Zenoh configuration of each agent, by name.
    pub agents: BTreeMap<String, PathBuf>,
}

/// The certificate authority's parameters (the same each time, so that a saved CA key can sign
/// more certificates later).
fn ca_params(ns: &str) -> CertificateParams {
    let mut p = CertificateParams::default();
    p.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    p.distinguished_name
        .push(DnType::CommonName, format!("v2x-fusion CA ({ns})"));
    p.key_usages = vec![
        KeyUsagePurpose::DigitalSignature,
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::CrlSign,
    ];
    p
}

fn validity(days: u32) -> (OffsetDateTime, OffsetDateTime) {
    let now = OffsetDateTime::now_utc();
    (now - Duration::hours(1), now + Duration::days(days as i64))
}

/// A certificate and key signed by `issuer`: a server certificate when `sans` are given, else a
/// client certificate with common name `cn`.
pub fn leaf(
    issuer: &Issuer<'_, KeyPair>,
    cn: &str,
    sans: &[String],
    not_before: OffsetDateTime,
    not_after: OffsetDateTime,
) -> anyhow::Result<(String, String)> {
    let mut p = CertificateParams::new(sans.to_vec()).context("certificate names")?;
    p.distinguished_name.push(DnType::CommonName, cn);
    p.use_authority_key_identifier_extension = true;
    p.key_usages = vec![
        KeyUsagePurpose::DigitalSignature,
        KeyUsagePurpose::KeyEncipherment,
    ];
    p.extended_key_usages = if sans.is_empty() {
        vec![ExtendedKeyUsagePurpose::ClientAuth]
    } else {
        vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ]
    };
    p.not_before = not_before;
    p.not_after = not_after;
    let key = KeyPair::generate()?;
    let cert = p.signed_by(&key, issuer)?;
    Ok((cert.pem(), key.serialize_pem()))
}

/// A new certificate authority: (certificate PEM, issuer).
pub fn new_ca(ns: &str, days: u32) -> anyhow::Result<(String, Issuer<'static, KeyPair>)> {
    let mut p = ca_params(ns);
    (p.not_before, p.not_after) = validity(days);
    let key = KeyPair::generate()?;
    let cert = p.self_signed(&key)?;
    Ok((cert.pem(), Issuer::new(ca_params(ns), key)))
}

/// The saved certificate authority of a directory `issue` wrote.
pub fn load_ca(dir: &Path, ns: &str) -> anyhow::Result<Issuer<'static, KeyPair>> {
    let path = dir.join("ca-key.pem");
    let pem = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let key = KeyPair::from_pem(&pem).with_context(|| format!("{}: not a key", path.display()))?;
    Ok(Issuer::new(ca_params(ns), key))
}

fn write(path: &Path, text: &str, secret: bool) -> anyhow::Result<()> {
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    #[cfg(unix)]
    if secret {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600))?;
    }
    let _ = secret;
    Ok(())
}

fn host_of(endpoint: &str) -> anyhow::Result<String> {
    let rest = endpoint
        .strip_prefix("tls/")
        .with_context(|| format!("endpoint '{endpoint}': a secure endpoint starts with tls/"))?;
    let rest = rest.split('#').next().unwrap_or(rest);
    let host = match rest.strip_prefix('[') {
        Some(v6) => v6.split(']').next().unwrap_or(v6),
        None => rest.rsplit_once(':').map_or(rest, |(h, _)| h),
    };
    if host.is_empty() {
        bail!("endpoint '{endpoint}' has no host");
    }
    Ok(host.to_string())
}

/// The Zenoh configuration of a client (fuser, agent, observer) with the given certificate.
pub fn client_config(ca: &Path, cert: &Path, key: &Path, connect: &[String]) -> Value {
    json!({
        "mode": "client",
        "connect": { "endpoints": connect, "timeout_ms": { "client": 30000 } },
        "scouting": { "multicast": { "enabled": false } },
        "transport": { "link": { "tls": {
            "root_ca_certificate": ca,
            "connect_certificate": cert,
            "connect_private_key": key,
            "enable_mtls": true,
            "verify_name_on_connect": true,
        },
            "rx": { "max_message_size": limits::MAX_MESSAGE },
        } },
    })
}

/// The Zenoh configuration of the router: mutual TLS on every listener, and the policy.
pub fn router_config(
    ca: &Path,
    cert: &Path,
    key: &Path,
    listen: &[String],
    policy: Value,
) -> Value {
    json!({
        "mode": "router",
        "listen": { "endpoints": listen },
        "scouting": { "multicast": { "enabled": false } },
        "transport": { "link": { "tls": {
            "root_ca_certificate": ca,
            "listen_certificate": cert,
            "listen_private_key": key,
            "enable_mtls": true,
        },
            "rx": { "max_message_size": limits::MAX_MESSAGE },
        } },
        "access_control": policy,
    })
}

/// Issues every certificate and writes every configuration into `cfg.out`.
pub fn issue(cfg: &CertsConfig) -> anyhow::Result<Issued> {
    keys::validate_chunk("namespace", &cfg.ns).map_err(anyhow::Error::msg)?;
    if cfg.agents.is_empty() {
        bail!("name at least one agent");
    }
    let mut seen = std::collections::BTreeSet::new();
    for a in &cfg.agents {
        wire::check_agent_name(a).map_err(|e| anyhow::anyhow!("agent '{a}': {e}"))?;
        if acl::reserved(a) {
            bail!("agent '{a}': the name belongs to another role's certificate");
        }
        if !seen.insert(a) {
            bail!("agent '{a}' is named twice");
        }
    }
    if cfg.days == 0 {
        bail!("--days must be at least 1");
    }
    std::fs::create_dir_all(&cfg.out)
        .with_context(|| format!("cannot create {}", cfg.out.display()))?;
    let dir = cfg
        .out
        .canonicalize()
        .with_context(|| format!("cannot resolve {}", cfg.out.display()))?;
    let (ca_pem, issuer) = new_ca(&cfg.ns, cfg.days)?;
    let ca = dir.join("ca.pem");
    write(&ca, &ca_pem, false)?;
    let ca_key = issuer.key().serialize_pem();
    write(&dir.join("ca-key.pem"), &ca_key, true)?;
    let (nb, na) = validity(cfg.days);
    let mut sans = vec!["localhost".to_string(), "127.0.0.1".to_string()];
    for e in cfg.connect.iter().chain(&cfg.listen) {
        let h = host_of(e)?;
        if h != "0.0.0.0" && h != "::" && !sans.contains(&h) {
            sans.push(h);
        }
    }
    let pair = |stem: &str, cn: &str, sans: &[String]| -> anyhow::Result<(PathBuf, PathBuf)> {
        let (cert, key) = leaf(&issuer, cn, sans, nb, na)?;
        let (c, k) = (
            dir.join(format!("{stem}.pem")),
            dir.join(format!("{stem}-key.pem")),
        );
        write(&c, &cert, false)?;
        write(&k, &key, true)?;
        Ok((c, k))
    };
    let (rc, rk) = pair("router", acl::ROUTER, &sans)?;
    let mut names: Vec<String> = cfg.agents.clone();
    names.sort();
    let router = dir.join("router.json5");
    let policy = acl::access_control(&cfg.ns, &names);
    write(
        &router,
        &serde_json::to_string_pretty(&router_config(&ca, &rc, &rk, &cfg.listen, policy))?,
        false,
    )?;
    let client = |stem: &str, cn: &str| -> anyhow::Result<PathBuf> {
        let (c, k) = pair(stem, cn, &[])?;
        let path = dir.join(format!("{stem}.json5"));
        let conf = client_config(&ca, &c, &k, &cfg.connect);
        write(&path, &serde_json::to_string_pretty(&conf)?, false)?;
        Ok(path)
    };
    let fuser = client("fuser", acl::FUSER)?;
    let observer = client("observer", acl::OBSERVER)?;
    let mut agents = BTreeMap::new();
    for a in &cfg.agents {
        agents.insert(a.clone(), client(&format!("agent-{a}"), a)?);
    }
    Ok(Issued {
        dir,
        ca,
        router,
        fuser,
        observer,
        agents,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_every_role_and_refuses_bad_names() {
        let out = std::env::temp_dir().join(format!("v2x-certs-test-{}", std::process::id()));
        let cfg = CertsConfig {
            out: out.clone(),
            ns: "demo".into(),
            agents: vec!["veh".into(), "rsu".into()],
            listen: vec!["tls/0.0.0.0:7447".into()],
            connect: vec!["tls/10.1.2.3:7447".into()],
            days: 30,
        };
        let issued = issue(&cfg).unwrap();
        for p in [&issued.ca, &issued.router, &issued.fuser, &issued.observer] {
            assert!(p.exists(), "{}", p.display());
        }
        let router: Value =
            serde_json::from_str(&std::fs::read_to_string(&issued.router).unwrap()).unwrap();
        assert_eq!(router["access_control"]["default_permission"], "deny");
        assert_eq!(router["transport"]["link"]["tls"]["enable_mtls"], true);
        assert_eq!(
            router["transport"]["link"]["rx"]["max_message_size"],
            limits::MAX_MESSAGE
        );
        let veh: Value =
            serde_json::from_str(&std::fs::read_to_string(&issued.agents["veh"]).unwrap()).unwrap();
        assert_eq!(veh["connect"]["endpoints"][0], "tls/10.1.2.3:7447");
        assert!(zenoh::Config::from_file(&issued.router).is_ok());
        assert!(zenoh::Config::from_file(&issued.agents["rsu"]).is_ok());
        // the router's certificate names the host clients connect to
        let pem = std::fs::read_to_string(issued.dir.join("router.pem")).unwrap();
        assert!(pem.contains("BEGIN CERTIFICATE"));
        assert!(load_ca(&issued.dir, "demo").is_ok());
        for bad in [
            vec!["fuser".to_string()],
            vec!["a/b".into()],
            vec!["x".into(), "x".into()],
        ] {
            assert!(issue(&CertsConfig {
                agents: bad,
                ..cfg.clone()
            })
            .is_err());
        }
        assert!(host_of("tcp/1.2.3.4:7447").is_err());
        assert_eq!(host_of("tls/[::1]:7447").unwrap(), "::1");
        let _ = std::fs::remove_dir_all(&out);
    }
}
