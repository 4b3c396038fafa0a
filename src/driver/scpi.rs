//! The one way the SCPI drivers talk to their instrument: send, ask, typed asks, a reply that may
//! take long (its timeout passed with the call), blocks, and the error-queue check after a batch.
//! Every failure comes back as a [`DriverError`] naming the instrument and the command.

use std::time::Duration;

use super::error::{session, DriverError};
use super::identity;
use super::io::InstrumentIo;
use crate::catalog::InstrumentModel;
use crate::session::{parse_bool, parse_f64, parse_i64, without_header, Block, DeviceError};
use crate::session::{Identity, SessionError};

/// An instrument's session, seen through its name.
pub struct Scpi {
    io: Box<dyn InstrumentIo>,
    name: String,
}

impl Scpi {
    /// `name` is how errors name the instrument (`awg`, `scope`).
    pub fn new(io: Box<dyn InstrumentIo>, name: &str) -> Scpi {
        Scpi {
            io,
            name: name.to_string(),
        }
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// The resource, for messages.
    pub(crate) fn resource_text(&self) -> String {
        self.io.resource_text()
    }

    /// The transport protocol (`vicp`, `hislip`, ...).
    pub fn protocol(&self) -> &'static str {
        self.io.protocol()
    }

    /// A session error, named with this instrument.
    pub fn failed(&self, source: SessionError) -> DriverError {
        session(&self.name)(source)
    }

    /// An error for a reply the driver cannot read.
    pub(crate) fn reply_error(
        &self,
        command: &str,
        expected: &'static str,
        reply: &str,
    ) -> DriverError {
        DriverError::Reply {
            instrument: self.name.clone(),
            command: command.to_string(),
            expected,
            reply: reply.to_string(),
        }
    }

    /// Sends `command`; no reply is read.
    ///
    /// # Errors
    ///
    /// [`DriverError::Session`] when the command cannot be written.
    pub async fn send(&mut self, command: &str) -> Result<(), DriverError> {
        self.io.write(command).await.map_err(session(&self.name))
    }

    /// The reply to `query`, without its terminator.
    pub(crate) async fn ask(&mut self, query: &str) -> Result<String, DriverError> {
        self.io.query(query).await.map_err(session(&self.name))
    }

    /// Like [`ask`](Self::ask), but the reply may take up to `timeout` to start. The timeout is
    /// this call's alone; the session's own is never changed.
    pub(crate) async fn ask_within(
        &mut self,
        query: &str,
        timeout: Duration,
    ) -> Result<String, DriverError> {
        self.io
            .query_with_timeout(query, timeout)
            .await
            .map_err(session(&self.name))
    }

    /// The replies to several queries sent as one message (IEEE 488.2 compound query: `A?;B?`
    /// is answered `a;b`), one round trip instead of one each. Replies must not hold a `;`
    /// themselves (numbers, enumerations, catalogs; not quoted strings).
    pub(crate) async fn ask_each(&mut self, queries: &[&str]) -> Result<Vec<String>, DriverError> {
        let message = queries.join(";");
        let reply = self.ask(&message).await?;
        let parts: Vec<String> = reply.split(';').map(|p| p.trim().to_string()).collect();
        if parts.len() != queries.len() {
            return Err(self.reply_error(
                &message,
                "one reply per query, separated by `;`",
                &reply,
            ));
        }
        Ok(parts)
    }

    /// A number, with or without a response header (`6.4E+10`, `VBS 6.4E+10`).
    #[cfg(test)]
    pub(crate) async fn ask_f64(&mut self, query: &str) -> Result<f64, DriverError> {
        let text = self.ask(query).await?;
        self.number_in(query, &text)
    }

    /// `text`, the reply to `query`, as a number (with or without a response header).
    pub(crate) fn number_in(&self, query: &str, text: &str) -> Result<f64, DriverError> {
        parse_f64(without_header(text.trim()))
            .ok_or_else(|| self.reply_error(query, "a number", text))
    }

    /// `text`, the reply to `query`, as `1`/`0`/`ON`/`OFF`.
    pub(crate) fn bool_in(&self, query: &str, text: &str) -> Result<bool, DriverError> {
        parse_bool(text).ok_or_else(|| self.reply_error(query, "0 or 1", text))
    }

    /// An integer, with or without a response header (`8193`, `INR 8193`).
    pub(crate) async fn ask_i64(&mut self, query: &str) -> Result<i64, DriverError> {
        let text = self.ask(query).await?;
        parse_i64(without_header(text.trim()))
            .ok_or_else(|| self.reply_error(query, "an integer", &text))
    }

    /// `1`/`0`/`ON`/`OFF`.
    #[cfg(test)]
    pub(crate) async fn ask_bool(&mut self, query: &str) -> Result<bool, DriverError> {
        let text = self.ask(query).await?;
        self.bool_in(query, &text)
    }

    /// A query answered with `1` once the instrument is done (`*OPC?`, or a message ending in
    /// it), allowed `timeout` to answer.
    pub(crate) async fn complete_within(
        &mut self,
        query: &str,
        timeout: Duration,
    ) -> Result<(), DriverError> {
        let text = self.ask_within(query, timeout).await?;
        match parse_i64(without_header(text.trim())) {
            Some(1) => Ok(()),
            _ => Err(self.reply_error(query, "1", &text)),
        }
    }

    /// Sends `header` followed by `payload` as a definite-length block.
    ///
    /// # Errors
    ///
    /// [`DriverError::Session`] when the block cannot be written.
    pub async fn write_block(&mut self, header: &str, payload: &[u8]) -> Result<(), DriverError> {
        self.io
            .write_block(header, payload)
            .await
            .map_err(session(&self.name))
    }

    /// The block in the reply to `query`.
    ///
    /// # Errors
    ///
    /// [`DriverError::Session`] when the query fails or the reply is not a well-formed block.
    pub async fn query_block(&mut self, query: &str) -> Result<Block, DriverError> {
        self.io
            .query_block(query)
            .await
            .map_err(session(&self.name))
    }

    /// Drains the error queue: whatever it held (empty when the instrument has nothing to say).
    pub(crate) async fn drain_errors(&mut self) -> Result<Vec<DeviceError>, DriverError> {
        self.io.errors().await.map_err(session(&self.name))
    }

    /// Drains the error queue after a batch and fails with [`DriverError::Refused`], naming the
    /// batch, if it held entries.
    ///
    /// # Errors
    ///
    /// [`DriverError::Refused`] when the queue held entries; [`DriverError::Session`] when reading it
    /// fails.
    pub async fn check(&mut self, batch: &str) -> Result<(), DriverError> {
        let errors = self.drain_errors().await?;
        self.refused_if_any(batch, errors)
    }

    /// [`DriverError::Refused`] for `errors`, or `Ok` when there are none.
    pub(crate) fn refused_if_any(
        &self,
        batch: &str,
        errors: Vec<DeviceError>,
    ) -> Result<(), DriverError> {
        if errors.is_empty() {
            Ok(())
        } else {
            Err(DriverError::Refused {
                instrument: self.name.clone(),
                batch: batch.to_string(),
                errors,
            })
        }
    }

    /// Asks `*IDN?` and checks the answer is the catalog model.
    ///
    /// # Errors
    ///
    /// [`DriverError::Session`] when the query fails; [`DriverError::Reply`] when the answer is not
    /// `manufacturer,model,serial,firmware`; [`DriverError::WrongInstrument`] when it names another model.
    pub async fn identify(&mut self, model: &InstrumentModel) -> Result<Identity, DriverError> {
        const IDN: &str = "*IDN?";
        let reply = self.ask(IDN).await?;
        identity::check(model, &self.name, &self.resource_text(), IDN, &reply)
    }
}

/// A number as SCPI text: a plain decimal rounded to 12 significant digits, so arithmetic noise
/// (`1.0239999999999999e-7`) never reaches the instrument (`64000000000`, `0.5`, `0.0000001024`).
pub(crate) fn number(value: f64) -> String {
    let rounded: f64 = format!("{value:.11e}").parse().unwrap_or(value);
    if rounded == 0.0 {
        "0".to_string()
    } else {
        format!("{rounded}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::driver::scripted::{block_on, Scripted, ERROR_CHECK};

    #[test]
    fn numbers_are_plain_decimals() {
        assert_eq!(number(64e9), "64000000000");
        assert_eq!(number(0.5), "0.5");
        assert_eq!(number(-0.0), "0");
        assert_eq!(number(1.024e-7), "0.0000001024");
        assert_eq!(number(1.024e-6 / 10.0 - 1e-22), "0.0000001024");
        assert_eq!(number(-5.12e-7), "-0.000000512");
    }

    #[test]
    fn typed_asks_accept_response_headers_and_name_bad_replies() {
        let fake = Scripted::new("fake")
            .reply("INR?", "INR 8193")
            .reply("RATE?", "+6.4000000000E+10")
            .reply("OUTP?", "ON")
            .reply("N?", "many");
        let mut scpi = Scpi::new(Box::new(fake), "scope");
        block_on(async {
            assert_eq!(scpi.ask_i64("INR?").await.unwrap(), 8193);
            assert_eq!(scpi.ask_f64("RATE?").await.unwrap(), 6.4e10);
            assert!(scpi.ask_bool("OUTP?").await.unwrap());
            let e = scpi.ask_i64("N?").await.unwrap_err();
            assert!(
                e.to_string().contains("scope") && e.to_string().contains("N?"),
                "{e}"
            );
        });
    }

    #[test]
    fn compound_queries_take_one_round_trip_and_count_their_replies() {
        let fake = Scripted::new("fake")
            .reply(":A?;:B?", "1;+2.5E+00")
            .reply(":A?;:C?", "1");
        let log = fake.log();
        let mut scpi = Scpi::new(Box::new(fake), "awg");
        block_on(async {
            let r = scpi.ask_each(&[":A?", ":B?"]).await.unwrap();
            assert_eq!(r, ["1", "+2.5E+00"]);
            assert_eq!(scpi.number_in(":B?", &r[1]).unwrap(), 2.5);
            assert!(scpi.bool_in(":A?", &r[0]).unwrap());
            let e = scpi.ask_each(&[":A?", ":C?"]).await.unwrap_err();
            assert!(
                e.to_string().contains(":A?;:C?") && e.to_string().contains("separated by `;`"),
                "{e}"
            );
        });
        assert_eq!(log.ops(), [":A?;:B?", ":A?;:C?"]);
    }

    #[test]
    fn the_per_call_timeout_goes_with_the_query() {
        let fake = Scripted::new("fake").reply("*OPC?", "1");
        let log = fake.log();
        let mut scpi = Scpi::new(Box::new(fake), "awg");
        block_on(scpi.complete_within("*OPC?", Duration::from_secs(60))).unwrap();
        assert_eq!(
            log.timeouts(),
            [("*OPC?".to_string(), Duration::from_secs(60))]
        );
    }

    #[test]
    fn a_batch_with_errors_is_refused_by_name() {
        let fake = Scripted::new("fake").refuse(":X 5", -222, "Data out of range");
        let log = fake.log();
        let mut scpi = Scpi::new(Box::new(fake), "awg");
        block_on(async {
            scpi.send(":X 5").await.unwrap();
            let e = scpi.check("the X batch").await.unwrap_err();
            assert!(
                e.to_string()
                    .contains("awg refused the X batch: -222,\"Data out of range\""),
                "{e}"
            );
            scpi.check("again").await.unwrap();
        });
        assert_eq!(log.ops(), [":X 5", ERROR_CHECK, ERROR_CHECK]);
    }
}
