//! Layer 2: IEEE 488.2 / SCPI on a [`Link`]: commands, queries with typed replies, arbitrary
//! blocks both ways, `*IDN?`, `*OPC?`, `*RST`, `*CLS`, and the error queue drained into typed
//! [`DeviceError`]s.
//!
//! Two rules keep replies honest:
//! * after a timeout the session clears the device (protocol device clear; a fresh connection on a
//!   raw socket), so a late reply is never read as the answer to the next query;
//! * "the instrument refused" ([`SessionError::Device`]) and "the link failed"
//!   ([`SessionError::Link`]) are different errors, each with a [`kind`](SessionError::kind);
//!   a query left unanswered while the error queue holds entries is
//!   [`SessionError::Unanswered`], with those entries, rather than a bare timeout. This holds on
//!   every transport: the error query is the instrument's own (`SYST:ERR?`, or the command error
//!   register `CMR?` of the LeCroy scopes, the only instruments speaking VICP).
//!
//! Devices with a [`LineProtocol`] (the serial Gotmic modules) answer every request with one
//! line; the session then reads every reply, adds the CRC when the device has it on, and reports
//! an `ERR` line as the device's refusal.

pub(crate) mod error;
pub(crate) mod line;
pub(crate) mod reply;

pub use line::{classify, LineReply};
pub use reply::{parse_error_entry, trim_reply, without_idn_header, BlockProblem};

pub(crate) use error::ErrorList;
pub use error::{DeviceError, SessionError};
pub use line::{Crc8, LineProtocol};
pub use reply::{parse_block, parse_f64, parse_i64, parse_idn, Block, BlockForm, Identity};
pub(crate) use reply::{parse_bool, register_error_text, without_header};

use crate::address::Resource;
use crate::transport::{Journal, Link, LinkError, LinkOptions};
use bytes::Bytes;
use std::time::Duration;

/// The longest the error queue is read for, in all, after a query went unanswered.
pub(crate) const ERROR_QUEUE_AFTER_TIMEOUT: Duration = Duration::from_secs(2);
/// The SCPI error queue: each read pops one `<code>,"<text>"` entry.
pub const SCPI_ERROR_QUERY: &str = "SYST:ERR?";
/// LeCroy's command error register (legacy IEEE 488.2 command set; cleared when read): the scopes
/// that speak VICP have no SCPI error queue.
pub(crate) const VICP_ERROR_QUERY: &str = "CMR?";

/// How a session talks to its instrument.
#[derive(Debug, Clone)]
pub struct SessionOptions {
    pub link: LinkOptions,
    /// The query that pops one error-queue entry, or reads an error register that clears when
    /// read (each non-zero value is one error). Empty: chosen by the transport, [`SCPI_ERROR_QUERY`]
    /// or, on VICP, `VICP_ERROR_QUERY`.
    pub error_query: String,
    /// At most this many entries are drained at once (a queue that never empties is reported).
    pub max_error_entries: usize,
    /// Set for devices that answer every request with one line (the Gotmic modules); `None` for
    /// IEEE 488.2 instruments, where only queries answer.
    pub line: Option<LineProtocol>,
}

impl Default for SessionOptions {
    fn default() -> Self {
        Self {
            link: LinkOptions::default(),
            error_query: String::new(),
            max_error_entries: 64,
            line: None,
        }
    }
}

/// The error query a session uses: the one given, else the transport's.
pub(crate) fn error_query_for(resource: &Resource, configured: &str) -> String {
    match (configured.trim(), resource) {
        ("", Resource::Vicp { .. }) => VICP_ERROR_QUERY.to_string(),
        ("", _) => SCPI_ERROR_QUERY.to_string(),
        (given, _) => given.to_string(),
    }
}

/// An open IEEE 488.2 session.
pub struct Session {
    link: Link,
    resource_text: String,
    options: SessionOptions,
    /// The error query in use (see [`SessionOptions::error_query`]).
    error_query: String,
    /// A line-protocol device has shown it frames lines with its CRC.
    crc_on: bool,
}

impl Session {
    /// Opens the resource with an optional journal; `instrument` names it in the journal.
    pub async fn open(
        resource: Resource,
        options: SessionOptions,
        journal: Option<Journal>,
        instrument: &str,
    ) -> Result<Self, SessionError> {
        let resource_text = resource.to_string();
        let link = Link::open_journalled(resource, options.link.clone(), journal, instrument)
            .await
            .map_err(|source| SessionError::Link {
                resource: resource_text.clone(),
                source,
            })?;
        Ok(Self::from_link(link, options))
    }

    /// A session over an already open link.
    pub fn from_link(link: Link, options: SessionOptions) -> Self {
        Self {
            resource_text: link.resource().to_string(),
            error_query: error_query_for(link.resource(), &options.error_query),
            link,
            options,
            crc_on: false,
        }
    }

    /// The query that reads the instrument's errors on this session.
    pub fn error_query(&self) -> &str {
        &self.error_query
    }

    /// Whether every request gets a reply line ([`SessionOptions::line`]): then
    /// `query_raw` is the way to send anything whose answer should be seen.
    pub fn answers_every_request(&self) -> bool {
        self.options.line.is_some()
    }

    pub fn resource(&self) -> &Resource {
        self.link.resource()
    }

    pub fn link(&mut self) -> &mut Link {
        &mut self.link
    }

    /// Changes timeouts, size limit or progress reporting for the next operations.
    pub fn link_options_mut(&mut self) -> &mut LinkOptions {
        self.link.options_mut()
    }

    fn link_err(&self, source: LinkError) -> SessionError {
        SessionError::Link {
            resource: self.resource_text.clone(),
            source,
        }
    }

    /// Handles a failed transfer: after a timeout, clear the device so a late reply is discarded.
    async fn after_failure(&mut self, source: LinkError) -> SessionError {
        if matches!(source, LinkError::Timeout { .. }) {
            if let Err(e) = self.link.device_clear().await {
                tracing::warn!(
                    "{}: device clear after a timeout failed ({e}); the link will be reopened before its next use",
                    self.resource_text
                );
            }
        }
        self.link_err(source)
    }

    fn check_command(&self, command: &str) -> Result<(), SessionError> {
        let line_end = self.link.line_end();
        if command.contains('\n') || command.bytes().any(|b| line_end.contains(&b)) {
            return Err(SessionError::CommandHasNewline {
                command: command.to_string(),
            });
        }
        Ok(())
    }

    /// Sends a command (the link's line end is appended: LF, or a serial line's terminator). On a line-protocol device the reply line is read
    /// too, and an `ERR` reply is the device's refusal.
    pub async fn write(&mut self, command: &str) -> Result<(), SessionError> {
        self.check_command(command)?;
        if self.options.line.is_some() {
            return self.line_exchange(command, None).await.map(drop);
        }
        let end = self.link.line_end().to_vec();
        self.send_parts(&[command.as_bytes(), &end]).await
    }

    async fn send_parts(&mut self, parts: &[&[u8]]) -> Result<(), SessionError> {
        match self.link.write_message(parts).await {
            Ok(()) => Ok(()),
            Err(e) => Err(self.after_failure(e).await),
        }
    }

    /// Reads one whole response message, terminator included.
    pub async fn read_raw(&mut self) -> Result<Bytes, SessionError> {
        self.read_raw_waiting(None).await
    }

    /// Reads one response message, waiting `read` (or the link's read timeout) for it to start.
    async fn read_raw_waiting(&mut self, read: Option<Duration>) -> Result<Bytes, SessionError> {
        let received = match read {
            Some(read) => self.link.read_message_within(read).await,
            None => self.link.read_message().await,
        };
        match received {
            Ok(m) => Ok(m),
            Err(e) => Err(self.after_failure(e).await),
        }
    }

    /// Sends a query and returns the raw reply. A query that gets no reply within the read
    /// timeout is usually one the instrument refused (488.2: a query in error has no answer), so
    /// the error queue is then read: its entries, if any, are the error instead of a bare timeout.
    ///
    /// On a line-protocol device the reply line comes back without its CRC, and an `ERR` line is
    /// the device's refusal ([`SessionError::Device`]).
    pub async fn query_raw(&mut self, query: &str) -> Result<Bytes, SessionError> {
        self.query_raw_waiting(query, None).await
    }

    /// [`query_raw`](Self::query_raw) with the reply allowed `read` (or the link's read timeout)
    /// to start; the link's own timeouts are never changed.
    async fn query_raw_waiting(
        &mut self,
        query: &str,
        read: Option<Duration>,
    ) -> Result<Bytes, SessionError> {
        if self.options.line.is_some() {
            self.check_command(query)?;
            let mut text = self.line_exchange(query, read).await?;
            text.push('\n');
            return Ok(Bytes::from(text));
        }
        match self.query_raw_plain(query, read).await {
            Err(SessionError::Link {
                source: timeout @ LinkError::Timeout { .. },
                ..
            }) if query != self.error_query => Err(self.refusal_or(query, timeout).await),
            other => other,
        }
    }

    async fn query_raw_plain(
        &mut self,
        query: &str,
        read: Option<Duration>,
    ) -> Result<Bytes, SessionError> {
        self.write(query).await?;
        self.read_raw_waiting(read).await
    }

    /// After `query` timed out (and the device was cleared): the instrument's error queue when
    /// it holds anything, else the timeout itself. Reading the queue gets at most
    /// min(read timeout, [`ERROR_QUEUE_AFTER_TIMEOUT`]) in all, so a hung instrument does not
    /// double the wait (an interrupted read leaves the link to be cleared before its next use).
    async fn refusal_or(&mut self, query: &str, timeout: LinkError) -> SessionError {
        let LinkError::Timeout { after, .. } = timeout else {
            return self.link_err(timeout);
        };
        let window = self
            .link
            .options()
            .timeouts
            .read
            .min(ERROR_QUEUE_AFTER_TIMEOUT);
        let errors = tokio::time::timeout(window, self.errors_waiting(Some(window))).await;
        match errors {
            Ok(Ok(errors)) if !errors.is_empty() => SessionError::Unanswered {
                resource: self.resource_text.clone(),
                query: query.to_string(),
                after,
                errors,
            },
            _ => self.link_err(timeout),
        }
    }

    /// One request and its reply line on a line-protocol device, CRC added and checked as the
    /// device has it; an `ERR` line is the device's refusal.
    async fn line_exchange(
        &mut self,
        request: &str,
        read: Option<Duration>,
    ) -> Result<String, SessionError> {
        let crc = self.options.line.as_ref().and_then(|l| l.crc);
        let reply = self.line_round_trip(request, crc, read).await?;
        let body = match crc {
            None => reply,
            Some(crc) => match crc.unframe(&reply) {
                Some(body) if !self.crc_on => {
                    // A framed reply: the device has CRC on. A plain request it refused (for its
                    // missing CRC) goes again, framed.
                    self.crc_on = true;
                    if matches!(line::classify(body), LineReply::Refused(_)) {
                        let again = self.line_round_trip(request, Some(crc), read).await?;
                        self.unframed(crc, request, &again)?
                    } else {
                        body.to_string()
                    }
                }
                Some(body) => body.to_string(),
                None if self.crc_on => self.unframed(crc, request, &reply)?,
                None => reply,
            },
        };
        match line::classify(&body) {
            LineReply::Refused(error) => Err(SessionError::Device {
                resource: self.resource_text.clone(),
                after: Some(request.to_string()),
                errors: vec![error],
            }),
            LineReply::Answer(text) => {
                if let (Some(on), Some(_)) = (line::crc_switch(request), crc) {
                    self.crc_on = on;
                }
                Ok(text)
            }
        }
    }

    fn unframed(&self, crc: Crc8, request: &str, reply: &str) -> Result<String, SessionError> {
        crc.unframe(reply).map(str::to_string).ok_or_else(|| {
            self.bad_reply(
                request,
                "a line ending in a valid *<hh> CRC-8 (check the cable and the line settings)",
                reply,
            )
        })
    }

    async fn line_round_trip(
        &mut self,
        request: &str,
        crc: Option<Crc8>,
        read: Option<Duration>,
    ) -> Result<String, SessionError> {
        let line = match crc {
            Some(crc) if self.crc_on => crc.frame(request),
            _ => request.to_string(),
        };
        let end = self.link.line_end().to_vec();
        self.send_parts(&[line.as_bytes(), &end]).await?;
        let raw = self.read_raw_waiting(read).await?;
        Ok(reply::trim_reply(&String::from_utf8_lossy(&raw)).to_string())
    }

    /// Sends a query and returns the reply as text without its terminator.
    pub async fn query(&mut self, query: &str) -> Result<String, SessionError> {
        let raw = self.query_raw(query).await?;
        Ok(reply::trim_reply(&String::from_utf8_lossy(&raw)).to_string())
    }

    /// Like [`query`](Self::query), but the reply may take up to `read` to start (a scope's
    /// `WAIT`, a long `*OPC?`). The timeout is this call's alone: the session's own timeouts are
    /// never changed, so a dropped call leaves nothing behind.
    pub(crate) async fn query_within(
        &mut self,
        query: &str,
        read: Duration,
    ) -> Result<String, SessionError> {
        let raw = self.query_raw_waiting(query, Some(read)).await?;
        Ok(reply::trim_reply(&String::from_utf8_lossy(&raw)).to_string())
    }

    fn bad_reply(&self, command: &str, expected: &'static str, reply: &str) -> SessionError {
        SessionError::Reply {
            resource: self.resource_text.clone(),
            command: command.to_string(),
            expected,
            reply: reply.chars().take(200).collect(),
        }
    }

    pub async fn query_f64(&mut self, query: &str) -> Result<f64, SessionError> {
        let text = self.query(query).await?;
        reply::parse_f64(&text).ok_or_else(|| self.bad_reply(query, "a finite number", &text))
    }

    pub async fn query_i64(&mut self, query: &str) -> Result<i64, SessionError> {
        let text = self.query(query).await?;
        reply::parse_i64(&text).ok_or_else(|| self.bad_reply(query, "an integer", &text))
    }

    /// A string reply with its quotes removed.
    pub async fn query_string(&mut self, query: &str) -> Result<String, SessionError> {
        let text = self.query(query).await?;
        Ok(reply::parse_string(&text))
    }

    /// Sends a query and returns the block in its reply (payload not copied). A query left
    /// unanswered is reported with the instrument's errors, as by `query_raw`.
    pub async fn query_block(&mut self, query: &str) -> Result<Block, SessionError> {
        let raw = self.query_raw(query).await?;
        self.parse_block_reply(query, raw)
    }

    fn parse_block_reply(&self, command: &str, raw: Bytes) -> Result<Block, SessionError> {
        reply::parse_block(raw.clone()).map_err(|problem| SessionError::Reply {
            resource: self.resource_text.clone(),
            command: command.to_string(),
            expected: "an IEEE 488.2 block",
            reply: format!(
                "{} (wanted {})",
                crate::transport::journal::escape_head(&raw),
                problem.describe()
            ),
        })
    }

    /// Sends `header` followed by `payload` as a block, e.g. `write_block(":TRAC1:DATA 1,0,", ..)`.
    /// The payload goes to the transport as is (no copy). An indefinite block is refused on a raw
    /// socket or serial link when the payload contains a newline (it would end the message).
    pub async fn write_block(
        &mut self,
        header: &str,
        payload: &[u8],
        form: BlockForm,
    ) -> Result<(), SessionError> {
        self.check_command(header)?;
        let block_header = match form {
            BlockForm::Definite => {
                reply::definite_header(payload.len() as u64).ok_or(SessionError::BlockTooLarge {
                    len: payload.len() as u64,
                })?
            }
            BlockForm::Indefinite => {
                if !self.link.has_message_end() && payload.contains(&b'\n') {
                    return Err(self.link_err(LinkError::IndefiniteBlockWithNewline {
                        protocol: self.link.resource().protocol(),
                    }));
                }
                "#0".to_string()
            }
        };
        let end = self.link.line_end().to_vec();
        self.send_parts(&[header.as_bytes(), block_header.as_bytes(), payload, &end])
            .await
    }

    /// `*IDN?`, parsed.
    pub async fn idn(&mut self) -> Result<Identity, SessionError> {
        let text = self.query("*IDN?").await?;
        reply::parse_idn(&text)
            .ok_or_else(|| self.bad_reply("*IDN?", "manufacturer,model,serial,firmware", &text))
    }

    /// `*OPC?`: waits until pending operations complete (the reply is `1`).
    pub async fn opc(&mut self) -> Result<(), SessionError> {
        let text = self.query("*OPC?").await?;
        match reply::parse_i64(&text) {
            Some(1) => Ok(()),
            _ => Err(self.bad_reply("*OPC?", "1", &text)),
        }
    }

    /// `*RST`, then `*OPC?` so the reset is complete on return.
    pub async fn rst(&mut self) -> Result<(), SessionError> {
        self.write("*RST").await?;
        self.opc().await
    }

    /// `*CLS`: clears the status registers and the error queue.
    pub async fn cls(&mut self) -> Result<(), SessionError> {
        self.write("*CLS").await
    }

    /// Drains the error queue; empty when the instrument has nothing to report. A line-protocol
    /// device has no queue (it refuses each request in its reply): always empty.
    pub async fn errors(&mut self) -> Result<Vec<DeviceError>, SessionError> {
        self.errors_waiting(None).await
    }

    async fn errors_waiting(
        &mut self,
        read: Option<Duration>,
    ) -> Result<Vec<DeviceError>, SessionError> {
        if self.options.line.is_some() {
            return Ok(Vec::new());
        }
        let query = self.error_query.clone();
        let mut found = Vec::new();
        for _ in 0..self.options.max_error_entries {
            let raw = self.query_raw_plain(&query, read).await?;
            let text = reply::trim_reply(&String::from_utf8_lossy(&raw)).to_string();
            let mut entry = reply::parse_error_entry(&text)
                .ok_or_else(|| self.bad_reply(&query, "<code>,\"<text>\"", &text))?;
            if entry.code == 0 {
                return Ok(found);
            }
            if entry.message.is_empty() {
                entry.message = reply::register_error_text(&query, entry.code).to_string();
            }
            found.push(entry);
        }
        Err(SessionError::ErrorQueueNotDraining {
            resource: self.resource_text.clone(),
            query,
            limit: self.options.max_error_entries,
        })
    }

    /// Drains the error queue and fails with [`SessionError::Device`] if it held anything.
    pub async fn check_errors(&mut self, after: Option<&str>) -> Result<(), SessionError> {
        let errors = self.errors().await?;
        if errors.is_empty() {
            Ok(())
        } else {
            Err(SessionError::Device {
                resource: self.resource_text.clone(),
                after: after.map(str::to_string),
                errors,
            })
        }
    }

    /// IEEE 488.2 device clear.
    pub async fn device_clear(&mut self) -> Result<(), SessionError> {
        self.link.device_clear().await.map_err(|e| self.link_err(e))
    }

    /// The status byte: the protocol's serial poll where there is one, `*STB?` otherwise.
    pub async fn read_stb(&mut self) -> Result<u8, SessionError> {
        match self.link.read_stb().await {
            Ok(stb) => Ok(stb),
            Err(LinkError::Unsupported { .. }) => {
                let text = self.query("*STB?").await?;
                reply::parse_i64(&text)
                    .and_then(|v| u8::try_from(v).ok())
                    .ok_or_else(|| self.bad_reply("*STB?", "a status byte 0..255", &text))
            }
            Err(e) => Err(self.after_failure(e).await),
        }
    }

    /// Reopens a lost connection; the session carries on with the same options and journal.
    pub async fn reconnect(&mut self) -> Result<(), SessionError> {
        self.link.reconnect().await.map_err(|e| self.link_err(e))
    }

    /// Closes the link (VXI-11 destroy_link).
    pub async fn close(&mut self) -> Result<(), SessionError> {
        self.link.close().await.map_err(|e| self.link_err(e))
    }
}
