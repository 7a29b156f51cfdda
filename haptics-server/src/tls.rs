//! Certificates and TLS configurations for both transports.
//!
//! The server presents one self-signed certificate (`haptics-server gen-cert`, or generated on
//! first start at the default location); the workstation *pins* it: the handshake succeeds
//! only if the server's end-entity certificate is byte-for-byte the pinned one, and the server
//! proves possession of its key with a TLS 1.3 signature (checked with ring's algorithms). No
//! CA, no host-name check: the pin is the identity. TLS 1.3 only; ALPN `haptics/1`.

use std::path::Path;

use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};

pub use haptics_client::tls::{
    ALPN, SERVER_NAME, TlsError, client_config, provider, read_cert, server_name,
};

/// A certificate and its private key.
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

/// TLS 1.3 server configuration presenting `id`, ALPN `haptics/1`.
pub fn server_config(id: &Identity) -> Result<rustls::ServerConfig, TlsError> {
    let mut cfg = rustls::ServerConfig::builder_with_provider(provider())
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(|e| TlsError::Config(e.to_string()))?
        .with_no_client_auth()
        .with_single_cert(vec![id.cert.clone()], id.key.clone_key())
        .map_err(|e| TlsError::Config(e.to_string()))?;
    cfg.alpn_protocols = vec![ALPN.to_vec()];
    Ok(cfg)
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
        client_config(back.cert).unwrap();
    }
}
