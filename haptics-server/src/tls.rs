//! Certificates and TLS configurations for both transports.
//!
//! The server presents one self-signed certificate (`haptics-server gen-cert`, or generated on
//! first start at the default location); the workstation *pins* it: the handshake succeeds
//! only if the server's end-entity certificate is byte-for-byte the pinned one, and the server
//! proves possession of its key with a TLS 1.3 signature (checked with ring's algorithms). No
//! CA, no host-name check: the pin is the identity. TLS 1.3 only; ALPN `haptics/1`.
//!
//! Clients are authenticated the same way round: each workstation presents a self-signed
//! client certificate (`haptics-server gen-cert --client`), and the server lists the ones it
//! accepts in its authorized-clients PEM file ([`AuthorizedClients`]). The TLS layer asks
//! every client for a certificate and checks that it holds the certificate's key (the TLS 1.3
//! `CertificateVerify` signature); whether that certificate is *authorized* is decided at
//! `Hello`, so an unauthorized client gets a named `Error { Unauthenticated }` (with the
//! fingerprint to add) rather than an opaque handshake failure. Why certificates and not a
//! pre-shared key: any TLS library can present one (Python's `ssl` included, which cannot
//! export keying material to bind a key to the channel), the private key never leaves the
//! workstation (the server stores only public certificates), and revoking a workstation is
//! deleting its certificate from the list.

use std::path::Path;
use std::sync::Arc;

use rustls::client::danger::HandshakeSignatureValid;
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer, UnixTime};
use rustls::server::danger::{ClientCertVerified, ClientCertVerifier};
use rustls::{DigitallySignedStruct, DistinguishedName, SignatureScheme};

pub use haptics_client::tls::{
    ALPN, CLIENT_FILES, Identity, SERVER_NAME, SignatureCheck, TlsError, client_config,
    identity_beside, provider, read_cert, read_identity, server_name,
};

/// The name in a generated client certificate.
pub const CLIENT_NAME: &str = "haptics-workstation";

/// A fresh self-signed identity for `haptics-server` and `localhost`.
pub fn generate() -> Result<Identity, TlsError> {
    let names = vec![SERVER_NAME.to_owned(), "localhost".to_owned()];
    let ck =
        rcgen::generate_simple_self_signed(names).map_err(|e| TlsError::Generate(e.to_string()))?;
    let key = PrivateKeyDer::try_from(ck.signing_key.serialize_der())
        .map_err(|e| TlsError::Generate(e.to_string()))?;
    Ok(Identity {
        cert: ck.cert.der().clone(),
        key,
    })
}

/// A fresh self-signed client identity for a workstation.
pub fn generate_client() -> Result<Identity, TlsError> {
    let ck = rcgen::generate_simple_self_signed(vec![CLIENT_NAME.to_owned()])
        .map_err(|e| TlsError::Generate(e.to_string()))?;
    let key = PrivateKeyDer::try_from(ck.signing_key.serialize_der())
        .map_err(|e| TlsError::Generate(e.to_string()))?;
    Ok(Identity {
        cert: ck.cert.der().clone(),
        key,
    })
}

pub use haptics_client::tls::fingerprint;

/// The client certificates the server accepts: exact DER matches, like the client's pin of the
/// server's certificate.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct AuthorizedClients {
    certs: Vec<CertificateDer<'static>>,
}

impl AuthorizedClients {
    /// Exactly these certificates.
    pub fn new(certs: Vec<CertificateDer<'static>>) -> Self {
        Self { certs }
    }

    /// Every certificate in a PEM file (one or more `CERTIFICATE` blocks; other blocks are
    /// ignored). An empty or unreadable file is an error naming it: a server that nobody can
    /// use is a configuration mistake.
    pub fn read(path: &Path) -> Result<Self, TlsError> {
        let err = |reason: String| TlsError::File {
            path: path.to_owned(),
            reason,
        };
        let certs = CertificateDer::pem_file_iter(path)
            .map_err(|e| {
                err(format!(
                    "cannot read the authorized client certificates: {e}"
                ))
            })?
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| err(format!("not a PEM certificate list: {e}")))?;
        if certs.is_empty() {
            return Err(err(
                "no CERTIFICATE in it: add a workstation's client.pem (haptics-server gen-cert --client)"
                    .into(),
            ));
        }
        Ok(Self { certs })
    }

    /// Whether `cert` is one of them.
    pub fn contains(&self, cert: &CertificateDer<'_>) -> bool {
        self.certs.iter().any(|c| c.as_ref() == cert.as_ref())
    }

    /// How many.
    pub fn len(&self) -> usize {
        self.certs.len()
    }

    /// None at all.
    pub fn is_empty(&self) -> bool {
        self.certs.is_empty()
    }
}

/// Append `cert` as a PEM block to the file at `path` (created if missing): an authorized
/// clients list, or a certificate file of its own.
pub fn append_certificate(path: &Path, cert: &CertificateDer<'_>) -> Result<(), TlsError> {
    use std::io::Write as _;
    let file_err = |e: std::io::Error| TlsError::File {
        path: path.to_owned(),
        reason: e.to_string(),
    };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(file_err)?;
    }
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .map_err(file_err)?;
    f.write_all(pem("CERTIFICATE", cert).as_bytes())
        .map_err(file_err)
}

/// Write `id` as PEM files (`key` readable by the owner only on Unix).
pub fn write_pem(id: &Identity, cert: &Path, key: &Path) -> Result<(), TlsError> {
    let file_err = |path: &Path, e: std::io::Error| TlsError::File {
        path: path.to_owned(),
        reason: e.to_string(),
    };
    for p in [cert, key] {
        if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| file_err(dir, e))?;
        }
    }
    std::fs::write(cert, pem("CERTIFICATE", &id.cert)).map_err(|e| file_err(cert, e))?;
    std::fs::write(key, pem("PRIVATE KEY", id.key.secret_der())).map_err(|e| file_err(key, e))?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(key, std::fs::Permissions::from_mode(0o600))
            .map_err(|e| file_err(key, e))?;
    }
    Ok(())
}

fn pem(label: &str, der: &[u8]) -> String {
    const B64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut b64 = String::new();
    for chunk in der.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                b64.push(B64[((n >> (18 - 6 * i)) & 63) as usize] as char);
            } else {
                b64.push('=');
            }
        }
    }
    let mut out = format!("-----BEGIN {label}-----\n");
    for line in b64.as_bytes().chunks(64) {
        out.push_str(std::str::from_utf8(line).unwrap_or_default());
        out.push('\n');
    }
    out.push_str(&format!("-----END {label}-----\n"));
    out
}

/// TLS 1.3 server configuration presenting `id`, ALPN `haptics/1`, asking every client for a
/// certificate (checked for possession of its key here, for authorization at `Hello`).
pub fn server_config(id: &Identity) -> Result<rustls::ServerConfig, TlsError> {
    let provider = provider();
    let verifier = Arc::new(AnyClientCert {
        signatures: SignatureCheck::new(Arc::clone(&provider)),
    });
    let mut cfg = rustls::ServerConfig::builder_with_provider(provider)
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(|e| TlsError::Config(e.to_string()))?
        .with_client_cert_verifier(verifier)
        .with_single_cert(vec![id.cert.clone()], id.key.clone_key())
        .map_err(|e| TlsError::Config(e.to_string()))?;
    cfg.alpn_protocols = vec![ALPN.to_vec()];
    Ok(cfg)
}

/// Asks for a client certificate, does not require one, and accepts any whose key the client
/// proves it holds: the authorization decision is made at `Hello` against
/// [`AuthorizedClients`], where a refusal can say why.
#[derive(Debug)]
struct AnyClientCert {
    signatures: SignatureCheck,
}

impl ClientCertVerifier for AnyClientCert {
    fn offer_client_auth(&self) -> bool {
        true
    }

    fn client_auth_mandatory(&self) -> bool {
        false
    }

    fn root_hint_subjects(&self) -> &[DistinguishedName] {
        &[]
    }

    fn verify_client_cert(
        &self,
        _end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _now: UnixTime,
    ) -> Result<ClientCertVerified, rustls::Error> {
        Ok(ClientCertVerified::assertion())
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        self.signatures.tls12(message, cert, dss)
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        self.signatures.tls13(message, cert, dss)
    }

    fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
        self.signatures.schemes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_identity_round_trips_through_pem() {
        let dir = tempfile::tempdir().unwrap();
        let id = generate().unwrap();
        let (c, k) = (dir.path().join("c.pem"), dir.path().join("k.pem"));
        write_pem(&id, &c, &k).unwrap();
        let back = read_identity(&c, &k).unwrap();
        assert_eq!(back.cert, id.cert);
        assert_eq!(back.key.secret_der(), id.key.secret_der());
        server_config(&back).unwrap();
        client_config(back.cert, None).unwrap();
    }

    #[test]
    fn authorized_clients_read_every_certificate_and_match_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let list = dir.path().join("authorized_clients.pem");
        let (a, b, stranger) = (
            generate_client().unwrap(),
            generate_client().unwrap(),
            generate_client().unwrap(),
        );
        append_certificate(&list, &a.cert).unwrap();
        append_certificate(&list, &b.cert).unwrap();
        let auth = AuthorizedClients::read(&list).unwrap();
        assert_eq!(auth.len(), 2);
        assert!(auth.contains(&a.cert) && auth.contains(&b.cert));
        assert!(!auth.contains(&stranger.cert));
        client_config(generate().unwrap().cert, Some(&a)).unwrap();
        assert!(fingerprint(&a.cert).starts_with("sha256:"));
        assert_ne!(fingerprint(&a.cert), fingerprint(&b.cert));
        std::fs::write(&list, "").unwrap();
        let e = AuthorizedClients::read(&list).unwrap_err().to_string();
        assert!(
            e.contains("authorized_clients.pem") && e.contains("no CERTIFICATE"),
            "{e}"
        );
    }
}
