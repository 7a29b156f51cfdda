//! `workstation share-identity NAME`: a station's (or the router's) self-signed certificate and
//! key for a shared scene's mutual TLS. Its common name is NAME: for a station, the only name it
//! may edit and report under. The router lists the stations' certificates (concatenated, like
//! the haptics server's `authorized_clients.pem`); stations pin the router's.

use std::path::{Path, PathBuf};

use anyhow::Context as _;

/// Arguments of `workstation share-identity`.
#[derive(Debug, Clone, clap::Args)]
pub struct IdentityArgs {
    /// The station's name (or `router`): letters, digits, - _ and .
    pub name: String,
    /// Where NAME.pem and NAME.key are written.
    #[arg(long, default_value = "share-identities")]
    pub out: PathBuf,
    /// Also add the certificate to this list of authorized stations (created if missing).
    #[arg(long, value_name = "FILE")]
    pub authorize_in: Option<PathBuf>,
    /// A host name or address the certificate is valid for, besides NAME (repeatable): for the
    /// router, each name stations connect to it by (they check it), e.g. `--host localhost`
    /// on one machine, `--host lab-a.example` across a network. Stations need none.
    #[arg(long, value_name = "HOST")]
    pub host: Vec<String>,
}

/// `workstation share-identity`.
pub fn share_identity_command(args: &IdentityArgs) -> anyhow::Result<()> {
    let (cert, key) = write_identity(&args.out, &args.name, &args.host)?;
    println!("wrote {} and {}", cert.display(), key.display());
    if let Some(list) = &args.authorize_in {
        let pem = std::fs::read_to_string(&cert)?;
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(list)
            .with_context(|| format!("opening {}", list.display()))?;
        std::io::Write::write_all(&mut f, pem.as_bytes())
            .with_context(|| format!("writing {}", list.display()))?;
        println!("added `{}` to {}", args.name, list.display());
    }
    Ok(())
}

/// Make `dir/name.pem` and `dir/name.key` (the key readable by its owner only).
pub fn write_identity(
    dir: &Path,
    name: &str,
    hosts: &[String],
) -> anyhow::Result<(PathBuf, PathBuf)> {
    anyhow::ensure!(
        super::wire::valid_name(name),
        "name `{name}`: use 1-200 letters, digits, - _ or ."
    );
    let key = rcgen::KeyPair::generate().context("generating a key")?;
    let mut names = vec![name.to_owned(), "localhost".to_owned()];
    names.extend(hosts.iter().cloned());
    let mut params = rcgen::CertificateParams::new(names).context("certificate names")?;
    params.subject_alt_names.push(rcgen::SanType::IpAddress(
        std::net::Ipv4Addr::LOCALHOST.into(),
    ));
    params.distinguished_name = rcgen::DistinguishedName::new();
    params
        .distinguished_name
        .push(rcgen::DnType::CommonName, name);
    params.is_ca = rcgen::IsCa::ExplicitNoCa;
    params.key_usages = vec![rcgen::KeyUsagePurpose::DigitalSignature];
    params.extended_key_usages = vec![
        rcgen::ExtendedKeyUsagePurpose::ServerAuth,
        rcgen::ExtendedKeyUsagePurpose::ClientAuth,
    ];
    let cert = params
        .self_signed(&key)
        .context("signing the certificate")?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let (cert_path, key_path) = (
        dir.join(format!("{name}.pem")),
        dir.join(format!("{name}.key")),
    );
    std::fs::write(&cert_path, cert.pem())
        .with_context(|| format!("writing {}", cert_path.display()))?;
    write_private(&key_path, key.serialize_pem().as_bytes())?;
    Ok((cert_path, key_path))
}

fn write_private(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    use std::io::Write as _;
    use std::os::unix::fs::OpenOptionsExt as _;
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(0o600)
        .open(path)
        .with_context(|| format!("writing {}", path.display()))?;
    f.write_all(bytes)
        .with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_identity_names_its_station_and_lists_readably() {
        let dir = tempfile::tempdir().unwrap();
        let (cert, _) = write_identity(dir.path(), "west-1", &[]).unwrap();
        let (cert2, _) = write_identity(dir.path(), "east", &["lab-b.example".into()]).unwrap();
        let list = dir.path().join("authorized.pem");
        let both =
            std::fs::read_to_string(&cert).unwrap() + &std::fs::read_to_string(&cert2).unwrap();
        std::fs::write(&list, both).unwrap();
        assert_eq!(
            super::super::bus::authorized_names(&list).unwrap(),
            ["west-1", "east"]
        );
        assert!(write_identity(dir.path(), "a/b", &[]).is_err());
    }
}
