//! A scripted stand-in for a session, for driver tests that pin exact command sequences.
//!
//! The script maps each expected query to a list of canned replies (used in order), and can make
//! the instrument refuse a command (an entry appears in its error queue after the command) or the
//! link fail on it. Everything the driver does is recorded in order in a [`ScriptLog`]; the test
//! compares that log with the sequence it expects. A query with no canned reply left fails loudly:
//! the driver gets a protocol error naming the query, and the log lists it under
//! `ScriptLog::unexpected`.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bytes::Bytes;

use super::io::{BoxFuture, InstrumentIo};
use crate::session::{parse_block, Block, DeviceError, SessionError};
use crate::transport::LinkError;

/// The log entry of an error-queue drain.
pub const ERROR_CHECK: &str = "<error queue check>";
/// The log entry of a device clear.
pub const DEVICE_CLEAR: &str = "<device clear>";

/// A canned answer to a query.
#[derive(Debug, Clone)]
pub(crate) enum Canned {
    /// A text reply (without terminator).
    Text(String),
    /// A whole reply message that carries a block (prefix, `#<d><len>`, payload).
    Block(Bytes),
    /// The link fails instead of answering.
    Fail(Failure),
}

/// A simulated link failure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Failure {
    /// No reply within the timeout.
    Timeout,
    /// The instrument closed the connection.
    Closed,
}

#[derive(Debug, Default)]
struct Record {
    ops: Vec<String>,
    blocks: Vec<(String, Vec<u8>)>,
    unexpected: Vec<String>,
    timeouts: Vec<(String, Duration)>,
}

/// What a [`Scripted`] session saw; cloneable so the test keeps a handle after boxing the fake.
#[derive(Debug, Clone, Default)]
pub struct ScriptLog(Arc<Mutex<Record>>);

impl ScriptLog {
    fn with<T>(&self, f: impl FnOnce(&mut Record) -> T) -> T {
        let mut guard = self.0.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut guard)
    }

    /// Every operation in order: commands and queries as sent, blocks as
    /// `<header>#<N bytes>`, and [`ERROR_CHECK`] / [`DEVICE_CLEAR`].
    pub fn ops(&self) -> Vec<String> {
        self.with(|r| r.ops.clone())
    }

    /// The block writes: `(header, payload)`.
    pub fn blocks(&self) -> Vec<(String, Vec<u8>)> {
        self.with(|r| r.blocks.clone())
    }

    /// Queries that had no canned reply left.
    pub(crate) fn unexpected(&self) -> Vec<String> {
        self.with(|r| r.unexpected.clone())
    }

    /// The timeouts asked for with `query_with_timeout`: `(query, timeout)`.
    pub fn timeouts(&self) -> Vec<(String, Duration)> {
        self.with(|r| r.timeouts.clone())
    }

    /// Empties the log (to look at one operation after a setup).
    pub fn clear(&self) {
        self.with(|r| {
            r.ops.clear();
            r.blocks.clear();
        })
    }

    /// Panics with the list of unexpected queries, if any.
    ///
    /// # Panics
    ///
    /// When the driver sent a query the script did not expect: that is the assertion.
    pub fn assert_no_surprises(&self) {
        let unexpected = self.unexpected();
        assert!(
            unexpected.is_empty(),
            "the driver sent queries the script did not expect: {unexpected:?}"
        );
    }
}

/// A fake session answering from a script.
#[derive(Debug)]
pub struct Scripted {
    name: String,
    replies: HashMap<String, VecDeque<Canned>>,
    refusals: HashMap<String, VecDeque<DeviceError>>,
    write_failures: HashMap<String, Failure>,
    queue: Vec<DeviceError>,
    log: ScriptLog,
}

impl Scripted {
    /// An empty script; `name` appears in error messages as the resource.
    pub fn new(name: &str) -> Self {
        Self {
            name: name.to_string(),
            replies: HashMap::new(),
            refusals: HashMap::new(),
            write_failures: HashMap::new(),
            queue: Vec::new(),
            log: ScriptLog::default(),
        }
    }

    /// The log handle (clone it before boxing the fake into a driver).
    pub fn log(&self) -> ScriptLog {
        self.log.clone()
    }

    /// Queues one text reply to `query`.
    pub fn reply(mut self, query: &str, text: &str) -> Self {
        self.push(query, Canned::Text(text.to_string()));
        self
    }

    /// Queues the same text reply `times` times.
    pub fn reply_times(mut self, query: &str, text: &str, times: usize) -> Self {
        for _ in 0..times {
            self.push(query, Canned::Text(text.to_string()));
        }
        self
    }

    /// Queues a block reply: the whole message, e.g. `ALL,#9000000346...`.
    pub fn reply_block(mut self, query: &str, message: impl Into<Bytes>) -> Self {
        self.push(query, Canned::Block(message.into()));
        self
    }

    /// Makes the next `query` fail on the link.
    pub fn fail_query(mut self, query: &str, failure: Failure) -> Self {
        self.push(query, Canned::Fail(failure));
        self
    }

    /// Makes every write of `command` (or block with this header) fail on the link.
    pub fn fail_write(mut self, command: &str, failure: Failure) -> Self {
        self.write_failures.insert(command.to_string(), failure);
        self
    }

    /// After `command` (a command, a block header or a query) is sent, the instrument's error
    /// queue holds `code,"text"` (once per call of this method).
    pub fn refuse(mut self, command: &str, code: i32, text: &str) -> Self {
        self.refusals
            .entry(command.to_string())
            .or_default()
            .push_back(DeviceError {
                code,
                message: text.to_string(),
            });
        self
    }

    fn push(&mut self, query: &str, canned: Canned) {
        self.replies
            .entry(query.to_string())
            .or_default()
            .push_back(canned);
    }

    fn failure(&self, failure: Failure, op: &'static str) -> SessionError {
        let source = match failure {
            Failure::Timeout => LinkError::Timeout {
                op,
                after: Duration::from_millis(1),
            },
            Failure::Closed => LinkError::Closed { op },
        };
        SessionError::Link {
            resource: self.name.clone(),
            source,
        }
    }

    fn sent(&mut self, key: &str, entry: String) {
        self.log.with(|r| r.ops.push(entry));
        if let Some(errors) = self.refusals.get_mut(key) {
            if let Some(e) = errors.pop_front() {
                self.queue.push(e);
            }
        }
    }

    fn answer(&mut self, query: &str) -> Result<Canned, SessionError> {
        self.sent(query, query.to_string());
        match self.replies.get_mut(query).and_then(VecDeque::pop_front) {
            Some(Canned::Fail(f)) => Err(self.failure(f, "read")),
            Some(canned) => Ok(canned),
            None => {
                self.log.with(|r| r.unexpected.push(query.to_string()));
                Err(SessionError::Link {
                    resource: self.name.clone(),
                    source: LinkError::Protocol {
                        protocol: "scripted",
                        detail: format!(
                            "unexpected query `{query}`: the script has no reply left for it"
                        ),
                    },
                })
            }
        }
    }

    fn text(&mut self, query: &str) -> Result<String, SessionError> {
        match self.answer(query)? {
            Canned::Text(t) => Ok(t),
            Canned::Block(b) => Ok(String::from_utf8_lossy(&b).into_owned()),
            Canned::Fail(f) => Err(self.failure(f, "read")),
        }
    }

    fn check_write(&self, key: &str) -> Result<(), SessionError> {
        match self.write_failures.get(key) {
            Some(f) => Err(self.failure(*f, "write")),
            None => Ok(()),
        }
    }
}

impl InstrumentIo for Scripted {
    fn resource_text(&self) -> String {
        self.name.clone()
    }

    fn protocol(&self) -> &'static str {
        "scripted"
    }

    fn write<'a>(&'a mut self, command: &'a str) -> BoxFuture<'a, Result<(), SessionError>> {
        Box::pin(async move {
            self.sent(command, command.to_string());
            self.check_write(command)
        })
    }

    fn query<'a>(&'a mut self, query: &'a str) -> BoxFuture<'a, Result<String, SessionError>> {
        Box::pin(async move { self.text(query) })
    }

    fn query_with_timeout<'a>(
        &'a mut self,
        query: &'a str,
        timeout: Duration,
    ) -> BoxFuture<'a, Result<String, SessionError>> {
        Box::pin(async move {
            self.log
                .with(|r| r.timeouts.push((query.to_string(), timeout)));
            self.text(query)
        })
    }

    fn write_block<'a>(
        &'a mut self,
        header: &'a str,
        payload: &'a [u8],
    ) -> BoxFuture<'a, Result<(), SessionError>> {
        Box::pin(async move {
            self.sent(header, format!("{header}#<{} bytes>", payload.len()));
            self.log
                .with(|r| r.blocks.push((header.to_string(), payload.to_vec())));
            self.check_write(header)
        })
    }

    fn query_block<'a>(&'a mut self, query: &'a str) -> BoxFuture<'a, Result<Block, SessionError>> {
        Box::pin(async move {
            let message = match self.answer(query)? {
                Canned::Block(b) => b,
                Canned::Text(t) => Bytes::from(t.into_bytes()),
                Canned::Fail(f) => return Err(self.failure(f, "read")),
            };
            parse_block(message.clone()).map_err(|problem| SessionError::Reply {
                resource: self.name.clone(),
                command: query.to_string(),
                expected: "an IEEE 488.2 block",
                reply: format!(
                    "{} (wanted {})",
                    String::from_utf8_lossy(&message[..message.len().min(40)]),
                    problem.describe()
                ),
            })
        })
    }

    fn errors(&mut self) -> BoxFuture<'_, Result<Vec<DeviceError>, SessionError>> {
        Box::pin(async move {
            self.log.with(|r| r.ops.push(ERROR_CHECK.to_string()));
            Ok(std::mem::take(&mut self.queue))
        })
    }

    fn device_clear(&mut self) -> BoxFuture<'_, Result<(), SessionError>> {
        Box::pin(async move {
            self.log.with(|r| r.ops.push(DEVICE_CLEAR.to_string()));
            Ok(())
        })
    }
}

/// Runs a future to completion on a fresh single-threaded runtime (the layer's unit tests).
#[cfg(test)]
pub(crate) fn block_on<T>(f: impl std::future::Future<Output = T>) -> T {
    tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .expect("a test runtime")
        .block_on(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replies_come_in_order_and_surprises_are_loud() {
        let fake = Scripted::new("fake")
            .reply("A?", "1")
            .reply("A?", "2")
            .refuse(":X 5", -222, "Data out of range");
        let log = fake.log();
        let mut io: Box<dyn InstrumentIo> = Box::new(fake);
        block_on(async {
            assert_eq!(io.query("A?").await.unwrap(), "1");
            assert_eq!(io.query("A?").await.unwrap(), "2");
            let e = io.query("A?").await.unwrap_err();
            assert!(e.to_string().contains("unexpected query `A?`"), "{e}");
            io.write(":X 5").await.unwrap();
            let errors = io.errors().await.unwrap();
            assert_eq!(errors[0].code, -222);
            assert!(io.errors().await.unwrap().is_empty());
            io.write_block(":D ", &[1, 2, 3]).await.unwrap();
        });
        assert_eq!(
            log.ops(),
            [
                "A?",
                "A?",
                "A?",
                ":X 5",
                ERROR_CHECK,
                ERROR_CHECK,
                ":D #<3 bytes>"
            ]
        );
        assert_eq!(log.unexpected(), ["A?"]);
        assert_eq!(log.blocks()[0].1, vec![1, 2, 3]);
    }
}
