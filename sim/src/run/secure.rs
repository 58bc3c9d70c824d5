//! The Zenoh options of each role of a run: its scenario entry as given for a plain run; for a
//! mutual-TLS run, the configuration `v2x-sim certs` wrote for the role (its certificate, the CA,
//! the router as its only peer), with the scenario entry's options on top. A one-process run
//! issues its own certificates.

use crate::certs::{issue, CertsConfig, Issued};
use crate::scenario::{Scenario, SecurityMode};
use anyhow::{bail, Context};
use std::path::{Path, PathBuf};
use v2x_protocol::net::ZenohArgs;

/// A role of a run.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Role<'a> {
    /// The Zenoh router (mutual-TLS runs only).
    Router,
    /// The fuser.
    Fuser,
    /// An agent, by name.
    Agent(&'a str),
}

/// The configuration file of a role in a `v2x-sim certs` directory.
pub fn config_file(dir: &Path, role: Role) -> PathBuf {
    match role {
        Role::Router => dir.join("router.json5"),
        Role::Fuser => dir.join("fuser.json5"),
        Role::Agent(a) => dir.join(format!("agent-{a}.json5")),
    }
}

/// `args`, on top of the role's certificate configuration in `dir`.
pub fn with_certs(args: &ZenohArgs, dir: &Path, role: Role) -> anyhow::Result<ZenohArgs> {
    let mut out = args.clone();
    if out.zenoh_config.is_none() {
        let file = config_file(dir, role);
        if !file.exists() {
            bail!(
                "{} is missing: make the certificates with `v2x-sim certs --out {} ...`",
                file.display(),
                dir.display()
            );
        }
        out.zenoh_config = Some(file);
    }
    Ok(out)
}

/// The Zenoh options of a role when roles run on separate hosts.
pub fn role_args(scenario: &Scenario, role: Role) -> anyhow::Result<ZenohArgs> {
    let base = match role {
        Role::Router => &scenario.security.router,
        Role::Fuser => &scenario.fuser.zenoh,
        Role::Agent(a) => {
            &scenario
                .agents
                .iter()
                .find(|s| s.name == a)
                .context("an agent of this scenario")?
                .zenoh
        }
    };
    match scenario.security.mode {
        SecurityMode::Plain if role == Role::Router => {
            bail!("the router role belongs to a run with [security] mode = \"mtls\"")
        }
        SecurityMode::Plain => Ok(base.clone()),
        SecurityMode::Mtls => {
            let dir = scenario.security.certs.as_ref().context(
                "[security] certs: a mutual-TLS run on several hosts needs the directory that `v2x-sim certs` wrote, on every host",
            )?;
            with_certs(base, dir, role)
        }
    }
}

/// Certificates for a one-process run whose router listens on `endpoint`: the scenario's
/// directory if it names one, else fresh ones in a temporary directory.
pub fn local_certs(scenario: &Scenario, endpoint: &str) -> anyhow::Result<PathBuf> {
    if let Some(dir) = &scenario.security.certs {
        return Ok(dir.clone());
    }
    let out = std::env::temp_dir().join(format!(
        "v2x-sim-certs-{}-{}",
        scenario.namespace,
        std::process::id()
    ));
    let issued: Issued = issue(&CertsConfig {
        out,
        ns: scenario.namespace.clone(),
        agents: scenario.agents.iter().map(|a| a.name.clone()).collect(),
        listen: vec![endpoint.to_string()],
        connect: vec![endpoint.to_string()],
        days: 1,
    })?;
    Ok(issued.dir)
}
