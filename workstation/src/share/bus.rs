//! Zenoh sessions for shared scenes: the configuration every station, viewer and router uses
//! (client or router mode, no multicast scouting, mutual TLS), and who may write what.
//!
//! **Security.** With a `tls/` endpoint every link is mutual TLS: the router presents its
//! certificate (which stations pin as their only root) and accepts only clients whose
//! certificate is in its authorized list (the same kind of PEM list as the haptics server's
//! `authorized_clients.pem`: each station's self-signed certificate, made by
//! `workstation share-identity`). An unlisted peer's handshake fails: it gets nothing and
//! changes nothing. On top, the router's access control lets a listed station put only under its
//! own name (`…/propose/<station>`, `…/telemetry/<station>`): the name is its certificate's
//! common name, so a station cannot speak for another. Plain `tcp/` endpoints are for one
//! trusted machine or lab network (loopback tests, a demo): anyone who reaches them may join.

use std::path::{Path, PathBuf};

use anyhow::Context as _;

use super::ROOT;

/// Mutual-TLS files of a station or viewer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StationTls {
    /// The router's certificate, pinned (the only root trusted).
    pub router_cert: PathBuf,
    /// This station's certificate (its common name is the station's name).
    pub cert: PathBuf,
    /// Its private key.
    pub key: PathBuf,
}

/// Mutual-TLS files of a router.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RouterTls {
    /// The router's certificate.
    pub cert: PathBuf,
    /// Its private key.
    pub key: PathBuf,
    /// The listed stations' certificates (PEM, concatenated).
    pub authorized: PathBuf,
    /// Which of them are other sites' routers, relaying their stations.
    pub linked: Vec<String>,
}

fn base(mode: &str) -> anyhow::Result<zenoh::Config> {
    let mut c = zenoh::Config::default();
    set(&mut c, "mode", &json(mode))?;
    // Sites are linked by naming endpoints, never by multicast discovery.
    set(&mut c, "scouting/multicast/enabled", "false")?;
    set(&mut c, "scouting/gossip/enabled", "false")?;
    Ok(c)
}

fn json(s: &str) -> String {
    serde_json::to_string(s).expect("a string serialises")
}

fn set(c: &mut zenoh::Config, key: &str, value: &str) -> anyhow::Result<()> {
    c.insert_json5(key, value)
        .map_err(|e| anyhow::anyhow!("zenoh configuration {key} = {value}: {e}"))
}

fn existing(p: &Path, what: &str) -> anyhow::Result<String> {
    anyhow::ensure!(
        p.is_file(),
        "{what} {} does not exist (make identities with `workstation share-identity`)",
        p.display()
    );
    Ok(json(&p.to_string_lossy()))
}

/// Mutual TLS with these files (`key` under `transport/link/tls`, the file, what it is for an
/// error). Zenoh 1.10's TLS client trusts the public web PKI roots beside the given root, so the
/// peer's name is checked too: a router's `tls/HOST:PORT` must be one of its certificate's names
/// (`share-identity router --host NAME`).
fn tls_files(c: &mut zenoh::Config, files: &[(&str, &Path, &str)]) -> anyhow::Result<()> {
    let k = "transport/link/tls";
    for (key, file, what) in files {
        set(c, &format!("{k}/{key}"), &existing(file, what)?)?;
    }
    set(c, &format!("{k}/enable_mtls"), "true")?;
    set(c, &format!("{k}/verify_name_on_connect"), "true")
}

/// Check an endpoint the way users write them: `tcp/HOST:PORT` or `tls/HOST:PORT`.
pub fn check_endpoint(endpoint: &str) -> anyhow::Result<()> {
    let ok = endpoint
        .strip_prefix("tcp/")
        .or_else(|| endpoint.strip_prefix("tls/"))
        .is_some_and(|a| {
            a.rsplit_once(':')
                .is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok())
        });
    anyhow::ensure!(
        ok,
        "endpoint `{endpoint}`: expected tcp/HOST:PORT or tls/HOST:PORT (e.g. tcp/127.0.0.1:7447)"
    );
    Ok(())
}

/// A client session's configuration: connect to `endpoint` (the router), with `tls` for a
/// `tls/` endpoint.
pub fn client_config(endpoint: &str, tls: Option<&StationTls>) -> anyhow::Result<zenoh::Config> {
    check_endpoint(endpoint)?;
    let mut c = base("client")?;
    set(
        &mut c,
        "connect/endpoints",
        &format!("[{}]", json(endpoint)),
    )?;
    // Keep trying while the router is away (a restart): the session comes back by itself.
    set(&mut c, "connect/timeout_ms", "-1")?;
    match (endpoint.starts_with("tls/"), tls) {
        (true, Some(t)) => tls_files(
            &mut c,
            &[
                (
                    "root_ca_certificate",
                    &t.router_cert,
                    "the router's certificate",
                ),
                ("connect_certificate", &t.cert, "the station's certificate"),
                ("connect_private_key", &t.key, "the station's key"),
            ],
        )?,
        (true, None) => anyhow::bail!(
            "{endpoint} is a TLS endpoint: give --share-ca (the router's certificate), --share-cert and --share-key"
        ),
        (false, Some(_)) => anyhow::bail!(
            "--share-cert/--share-key/--share-ca need a tls/ endpoint (got {endpoint})"
        ),
        (false, None) => {}
    }
    Ok(c)
}

/// The router's configuration: listen on `listen`, link to other routers at `connect`, and with
/// `tls`, accept only the listed stations and let each write only under its own name.
pub fn router_config(
    listen: &[String],
    connect: &[String],
    tls: Option<&RouterTls>,
) -> anyhow::Result<zenoh::Config> {
    anyhow::ensure!(!listen.is_empty(), "give at least one --listen endpoint");
    for e in listen.iter().chain(connect) {
        check_endpoint(e)?;
    }
    let list = |v: &[String]| {
        format!(
            "[{}]",
            v.iter().map(|e| json(e)).collect::<Vec<_>>().join(",")
        )
    };
    let mut c = base("router")?;
    set(&mut c, "listen/endpoints", &list(listen))?;
    if !connect.is_empty() {
        set(&mut c, "connect/endpoints", &list(connect))?;
    }
    let any_tls = listen.iter().chain(connect).any(|e| e.starts_with("tls/"));
    match (any_tls, tls) {
        (true, Some(t)) => {
            tls_files(
                &mut c,
                &[
                    ("listen_certificate", &t.cert, "the router's certificate"),
                    ("listen_private_key", &t.key, "the router's key"),
                    (
                        "root_ca_certificate",
                        &t.authorized,
                        "the authorized stations",
                    ),
                    // Its own links to other routers (--connect) present the same identity.
                    ("connect_certificate", &t.cert, "the router's certificate"),
                    ("connect_private_key", &t.key, "the router's key"),
                ],
            )?;
            let names = authorized_names(&t.authorized)?;
            for l in &t.linked {
                anyhow::ensure!(
                    names.contains(l),
                    "--linked-router {l}: no certificate named `{l}` in {} (a linked router is listed like a station)",
                    t.authorized.display()
                );
            }
            set(&mut c, "access_control", &access_control(&names, &t.linked))?;
        }
        (true, None) => anyhow::bail!(
            "a tls/ endpoint needs --tls-cert, --tls-key and --authorized (the stations' certificates)"
        ),
        (false, Some(_)) => anyhow::bail!("--tls-cert/--tls-key/--authorized need a tls/ endpoint"),
        (false, None) => {}
    }
    Ok(c)
}

/// The common names of the certificates in a PEM list (each listed station's name).
pub fn authorized_names(path: &Path) -> anyhow::Result<Vec<String>> {
    let pem = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let mut names = Vec::new();
    for (i, p) in x509_parser::pem::Pem::iter_from_buffer(&pem).enumerate() {
        let p = p.map_err(|e| anyhow::anyhow!("{}: PEM block {}: {e}", path.display(), i + 1))?;
        let cert = p
            .parse_x509()
            .map_err(|e| anyhow::anyhow!("{}: certificate {}: {e}", path.display(), i + 1))?;
        let cn = cert
            .subject()
            .iter_common_name()
            .next()
            .and_then(|c| c.as_str().ok())
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "{}: certificate {} has no common name (the station's name)",
                    path.display(),
                    i + 1
                )
            })?;
        anyhow::ensure!(
            super::wire::valid_name(cn),
            "{}: certificate {}: common name `{cn}` is not a station name (letters, digits, - _ .)",
            path.display(),
            i + 1
        );
        names.push(cn.to_owned());
    }
    anyhow::ensure!(
        !names.is_empty(),
        "{}: no certificate in it",
        path.display()
    );
    Ok(names)
}

/// Access control: every listed station reads everything under the root and writes only under
/// its own name; a linked site's router (`linked`, also listed) writes proposals and telemetry
/// under any name, relaying its own site's stations (whose names its own access control
/// checks). The router's own keeper is not a link and is not filtered.
pub fn access_control(stations: &[String], linked: &[String]) -> String {
    let mut rules = vec![
        format!(
            r#"{{ id: "read", messages: ["declare_subscriber", "query", "liveliness_query", "declare_liveliness_subscriber"], flows: ["ingress"], permission: "allow", key_exprs: ["{ROOT}/**"] }}"#
        ),
        format!(
            r#"{{ id: "deliver", messages: ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable", "liveliness_token", "liveliness_query", "declare_liveliness_subscriber"], flows: ["egress"], permission: "allow", key_exprs: ["{ROOT}/**"] }}"#
        ),
    ];
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    rules.push(format!(
        r#"{{ id: "relay", messages: ["put"], flows: ["ingress"], permission: "allow", key_exprs: ["{ROOT}/*/propose/*", "{ROOT}/*/telemetry/*"] }}"#
    ));
    for (i, s) in stations.iter().enumerate() {
        let own = if linked.contains(s) {
            "relay".to_owned()
        } else {
            rules.push(format!(
                r#"{{ id: "own-{i}", messages: ["put"], flows: ["ingress"], permission: "allow", key_exprs: ["{ROOT}/*/propose/{s}", "{ROOT}/*/telemetry/{s}"] }}"#
            ));
            format!("own-{i}")
        };
        subjects.push(format!(
            r#"{{ id: "s-{i}", cert_common_names: [{}] }}"#,
            json(s)
        ));
        policies.push(format!(
            r#"{{ rules: ["read", "deliver", "{own}"], subjects: ["s-{i}"] }}"#
        ));
    }
    format!(
        "{{ enabled: true, default_permission: \"deny\", rules: [{}], subjects: [{}], policies: [{}] }}",
        rules.join(", "),
        subjects.join(", "),
        policies.join(", ")
    )
}

/// Open a session, saying where it failed.
pub async fn open(config: zenoh::Config, what: &str) -> anyhow::Result<zenoh::Session> {
    zenoh::open(config)
        .await
        .map_err(|e| anyhow::anyhow!("opening the {what}'s Zenoh session: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_are_checked_and_tls_needs_its_files() {
        assert!(check_endpoint("tcp/127.0.0.1:7447").is_ok());
        assert!(check_endpoint("tls/lab-a.example:7448").is_ok());
        for bad in [
            "127.0.0.1:7447",
            "udp/1.2.3.4:5",
            "tcp/:7447",
            "tcp/host:port",
        ] {
            assert!(check_endpoint(bad).is_err(), "{bad}");
        }
        let e = client_config("tls/127.0.0.1:7448", None).unwrap_err();
        assert!(e.to_string().contains("--share-ca"), "{e}");
        assert!(client_config("tcp/127.0.0.1:7447", None).is_ok());
        let e = router_config(&["tls/0.0.0.0:7448".into()], &[], None).unwrap_err();
        assert!(e.to_string().contains("--authorized"), "{e}");
    }

    #[test]
    fn the_access_control_is_valid_zenoh_configuration() {
        let mut c = zenoh::Config::default();
        let ac = access_control(
            &["a".into(), "west-2".into(), "site-b".into()],
            &["site-b".into()],
        );
        c.insert_json5("access_control", &ac)
            .unwrap_or_else(|e| panic!("{e}: {ac}"));
        assert!(ac.contains("haptic-sculpt/*/propose/west-2"));
        assert!(
            ac.contains(r#"rules: ["read", "deliver", "relay"], subjects: ["s-2"]"#),
            "{ac}"
        );
    }
}
