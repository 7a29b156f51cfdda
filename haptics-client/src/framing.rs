//! The control channel's framing over any byte stream (TLS-over-TCP or a QUIC stream), shared
//! by the server and the client.

use protocol::control::ControlError;
use protocol::{Control, FrameDecoder};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

/// Why the network side failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TransportError {
    /// Socket I/O.
    #[error("I/O: {0}")]
    Io(#[from] std::io::Error),
    /// The peer broke the control protocol.
    #[error("control channel: {0}")]
    Control(#[from] ControlError),
    /// The peer took too long.
    #[error("timed out waiting for {0}")]
    Timeout(&'static str),
    /// QUIC connection error.
    #[error("QUIC: {0}")]
    Quic(String),
}

/// Write one control message.
pub async fn write_control<W: AsyncWrite + Unpin>(
    wr: &mut W,
    msg: &Control,
) -> std::io::Result<()> {
    wr.write_all(&msg.to_frame()).await?;
    wr.flush().await
}

/// Read the next control message; `Ok(None)` when the stream closed cleanly.
pub async fn read_control<R: AsyncRead + Unpin>(
    rd: &mut R,
    dec: &mut FrameDecoder,
) -> Result<Option<Control>, TransportError> {
    let mut buf = [0u8; 4096];
    loop {
        if let Some(msg) = dec.next_message()? {
            return Ok(Some(msg));
        }
        let n = rd.read(&mut buf).await?;
        if n == 0 {
            return Ok(None);
        }
        dec.push(&buf[..n]);
    }
}
