//! TLS for the workstation side: the pinned-certificate verifier and the client configuration.
//!
//! The server presents one self-signed certificate; the client *pins* it: the handshake
//! succeeds only if the server's end-entity certificate is byte-for-byte the pinned one, and
//! the server proves possession of its key with a TLS 1.3 signature (checked with ring's
//! algorithms). No CA, no host-name check: the pin is the identity. TLS 1.3 only; ALPN
//! `haptics/1`.
//!
//! The other way round, the workstation presents its own [`Identity`], a self-signed *client*
//! certificate that the server pins in its authorized list: only a listed workstation gets a
//! session. [`identity_beside`] finds the pair a server created next to its own certificate,
//! so a workstation on the same machine needs no extra step.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::crypto::CryptoProvider;
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer, ServerName, UnixTime};
use rustls::{DigitallySignedStruct, SignatureScheme};

/// ALPN protocol id of both transports.
pub const ALPN: &[u8] = b"haptics/1";
/// The name the client asks for (the certificate also carries `localhost`).
pub const SERVER_NAME: &str = "haptics-server";

/// Why a certificate could not be made, read or used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TlsError {
    /// Generating the certificate failed.
    #[error("certificate generation failed: {0}")]
    Generate(String),
    /// Reading or writing a PEM file failed.
    #[error("{path}: {reason}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// rustls refused the configuration.
    #[error("TLS configuration: {0}")]
    Config(String),
}

/// File names of the workstation's identity, next to the server's `cert.pem` when the server
/// created them (certificate, private key).
pub const CLIENT_FILES: (&str, &str) = ("client.pem", "client.key");

/// A certificate and its private key (the server's, or a workstation's client identity).
#[derive(Debug)]
pub struct Identity {
    /// The certificate, DER.
    pub cert: CertificateDer<'static>,
    /// The private key, DER.
    pub key: PrivateKeyDer<'static>,
}

impl Clone for Identity {
    fn clone(&self) -> Self {
        Self {
            cert: self.cert.clone(),
            key: self.key.clone_key(),
        }
    }
}

/// Read a certificate and its PEM private key.
pub fn read_identity(cert: &Path, key: &Path) -> Result<Identity, TlsError> {
    let key_der = PrivateKeyDer::from_pem_file(key).map_err(|e| TlsError::File {
        path: key.to_owned(),
        reason: format!("not a PEM private key: {e}"),
    })?;
    Ok(Identity {
        cert: read_cert(cert)?,
        key: key_der,
    })
}

/// The client identity files next to a server certificate (`client.pem`, `client.key` in its
/// folder), if both exist: where a server on this machine wrote them on first start.
pub fn identity_beside(server_cert: &Path) -> Option<(PathBuf, PathBuf)> {
    let dir = server_cert.parent()?;
    let (c, k) = (dir.join(CLIENT_FILES.0), dir.join(CLIENT_FILES.1));
    (c.is_file() && k.is_file()).then_some((c, k))
}

/// Read a PEM certificate (the first one in the file).
pub fn read_cert(path: &Path) -> Result<CertificateDer<'static>, TlsError> {
    CertificateDer::from_pem_file(path).map_err(|e| TlsError::File {
        path: path.to_owned(),
        reason: format!("not a PEM certificate: {e}"),
    })
}

/// The ring crypto provider (not aws-lc-rs: no cmake, fast to build).
pub fn provider() -> Arc<CryptoProvider> {
    Arc::new(rustls::crypto::ring::default_provider())
}

/// TLS 1.3 client configuration that accepts exactly the `pinned` server certificate and
/// presents `identity` as the client certificate (without one the server refuses the session
/// with `Error { Unauthenticated }`).
pub fn client_config(
    pinned: CertificateDer<'static>,
    identity: Option<&Identity>,
) -> Result<rustls::ClientConfig, TlsError> {
    let provider = provider();
    let verifier = Arc::new(PinnedCert {
        pinned,
        signatures: SignatureCheck::new(Arc::clone(&provider)),
    });
    let builder = rustls::ClientConfig::builder_with_provider(provider)
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(|e| TlsError::Config(e.to_string()))?
        .dangerous()
        .with_custom_certificate_verifier(verifier);
    let mut cfg = match identity {
        Some(id) => builder
            .with_client_auth_cert(vec![id.cert.clone()], id.key.clone_key())
            .map_err(|e| TlsError::Config(format!("client certificate: {e}")))?,
        None => builder.with_no_client_auth(),
    };
    cfg.alpn_protocols = vec![ALPN.to_vec()];
    Ok(cfg)
}

/// `sha256:` and the hex SHA-256 of a certificate's DER (what `openssl x509 -fingerprint
/// -sha256` prints, lower-case without colons).
pub fn fingerprint(cert: &CertificateDer<'_>) -> String {
    let digest = ring::digest::digest(&ring::digest::SHA256, cert.as_ref());
    let hex: String = digest.as_ref().iter().map(|b| format!("{b:02x}")).collect();
    format!("sha256:{hex}")
}

/// The server name the client sends (SNI).
pub fn server_name() -> ServerName<'static> {
    ServerName::try_from(SERVER_NAME)
        .unwrap_or_else(|_| ServerName::IpAddress(std::net::Ipv4Addr::LOCALHOST.into()))
}

/// Accepts only the pinned certificate; signatures checked with the provider's algorithms.
#[derive(Debug)]
struct PinnedCert {
    pinned: CertificateDer<'static>,
    signatures: SignatureCheck,
}

impl ServerCertVerifier for PinnedCert {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _server_name: &ServerName<'_>,
        _ocsp: &[u8],
        _now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        if end_entity.as_ref() == self.pinned.as_ref() {
            Ok(ServerCertVerified::assertion())
        } else {
            Err(rustls::Error::General(format!(
                "the server's certificate ({}) does not match the pinned certificate ({}): \
                 copy the server's current cert.pem to this workstation",
                fingerprint(end_entity),
                fingerprint(&self.pinned)
            )))
        }
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

/// Handshake signatures checked with a provider's algorithms: what a pinning verifier does
/// besides comparing the certificate, on either side (the client pinning the server here, the
/// server checking client certificates in `haptics-server`).
#[derive(Debug)]
pub struct SignatureCheck {
    provider: Arc<CryptoProvider>,
}

impl SignatureCheck {
    /// With `provider`'s signature algorithms.
    pub fn new(provider: Arc<CryptoProvider>) -> Self {
        Self { provider }
    }

    /// A TLS 1.2 handshake signature.
    pub fn tls12(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls12_signature(
            message,
            cert,
            dss,
            &self.provider.signature_verification_algorithms,
        )
    }

    /// A TLS 1.3 handshake signature (`CertificateVerify`).
    pub fn tls13(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls13_signature(
            message,
            cert,
            dss,
            &self.provider.signature_verification_algorithms,
        )
    }

    /// The schemes those checks accept.
    pub fn schemes(&self) -> Vec<SignatureScheme> {
        self.provider
            .signature_verification_algorithms
            .supported_schemes()
    }
}
