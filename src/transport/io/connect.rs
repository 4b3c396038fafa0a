//! Opening a TCP connection to an instrument.

use super::options::LinkOptions;
use super::write::io_error;
use crate::transport::error::LinkError;

/// Connects a TCP stream within the connect timeout, with Nagle off (small commands go out at once).
pub(crate) async fn connect_tcp(
    host: &str,
    port: u16,
    protocol: &'static str,
    options: &LinkOptions,
) -> Result<tokio::net::TcpStream, LinkError> {
    let host_only = host.trim_start_matches('[').trim_end_matches(']');
    let target = format!("{host}:{port}");
    let connect = tokio::net::TcpStream::connect((host_only, port));
    let stream = match tokio::time::timeout(options.timeouts.connect, connect).await {
        Err(_) => {
            return Err(LinkError::Connect {
                target,
                protocol,
                source: std::io::Error::new(
                    std::io::ErrorKind::TimedOut,
                    format!(
                        "no answer within {}",
                        crate::transport::error::Rounded(options.timeouts.connect)
                    ),
                ),
            })
        }
        Ok(Err(source)) if source.kind() == std::io::ErrorKind::InvalidInput => {
            return Err(LinkError::Resolve {
                host: host.to_string(),
            })
        }
        Ok(Err(source)) => {
            return Err(LinkError::Connect {
                target,
                protocol,
                source,
            })
        }
        Ok(Ok(s)) => s,
    };
    stream
        .set_nodelay(true)
        .map_err(|e| io_error("connect", e))?;
    Ok(stream)
}
