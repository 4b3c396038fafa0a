//! `radbench scpi ADDRESS [COMMAND ...]`: sends SCPI commands one-shot, or at an interactive prompt
//! with history when no command is given. A command ending in `?` reads a reply; binary replies are
//! summarised (length, SHA-256, first bytes) and can be saved with `--save-binary`. Replies are
//! the instrument's bytes: control characters in them are shown escaped, never sent to the
//! terminal raw.
//!
//! At the prompt, Ctrl-C while a command runs abandons it, clears the device (so a late reply is
//! never taken for the next answer) and keeps the session. History (`~/.radbench_scpi_history`)
//! is written after every line entered, so no way of leaving loses it, and neither read nor
//! written when standard input is not a terminal (commands piped in are not history).

use super::bounded::Budget;
use super::progress::TransferBar;
use super::terminal::{is_stdout_closed, out, printable, printable_bytes};
use anyhow::Context;
use bytes::Bytes;
use radbench::address::Resource;
use radbench::session;
use radbench::session::{Session, SessionError, SessionOptions};
use radbench::transport;
use radbench::transport::{Journal, Timeouts};
use std::future::Future;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Duration;

/// How to reach an instrument: shared by `idn` and `scpi`.
#[derive(Debug, Clone, clap::Args)]
pub struct ConnectArgs {
    /// Resource string, e.g. TCPIP0::192.168.1.5::hislip0::INSTR, TCPIP::host::5025::SOCKET,
    /// TCPIP::host,PORT::inst0::INSTR, VICP::host, ASRL/dev/ttyUSB0::INSTR.
    #[arg(value_name = "ADDRESS")]
    pub address: String,
    /// Seconds allowed for a reply to start (long transfers get more, see --min-rate).
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    pub timeout: f64,
    /// Seconds allowed to connect.
    #[arg(long, default_value_t = 5.0, value_name = "SECONDS")]
    pub connect_timeout: f64,
    /// Seconds allowed for a small write to be accepted.
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    pub write_timeout: f64,
    /// Slowest healthy transfer rate in MB/s: a transfer of N MB gets N/rate extra seconds.
    #[arg(long, default_value_t = 10.0, value_name = "MB_PER_S")]
    pub min_rate: f64,
    /// Keep binary messages beside the --trace-io journal (in <journal>.blobs/).
    #[arg(long)]
    pub trace_io_keep_binary: bool,
    /// Serial speed for ASRL resources, in baud (1 ..= 12000000).
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
}

/// Fastest serial line speed accepted (USB-serial bridges reach 12 Mbaud).
const MAX_BAUD: u32 = 12_000_000;

fn seconds(value: f64, flag: &str) -> anyhow::Result<Duration> {
    if value.is_finite() && value > 0.0 && value <= 86_400.0 {
        Ok(Duration::from_secs_f64(value))
    } else {
        Err(radbench::exit::bad_input(format!(
            "--{flag} {value}: give a number of seconds between 0 and 86400"
        )))
    }
}

impl ConnectArgs {
    pub fn session_options(&self) -> anyhow::Result<SessionOptions> {
        if !(self.min_rate.is_finite() && self.min_rate > 0.0) {
            return Err(radbench::exit::bad_input(format!(
                "--min-rate {}: give a positive rate in MB/s",
                self.min_rate
            )));
        }
        let mut options = SessionOptions::default();
        options.link.timeouts = Timeouts {
            connect: seconds(self.connect_timeout, "connect-timeout")?,
            read: seconds(self.timeout, "timeout")?,
            write: seconds(self.write_timeout, "write-timeout")?,
            min_rate_bytes_per_s: (self.min_rate * 1e6) as u64,
        };
        if !(1..=MAX_BAUD).contains(&self.baud) {
            return Err(radbench::exit::bad_input(format!(
                "--baud {}: give the serial line speed in baud, 1 ..= {MAX_BAUD} (e.g. 115200)",
                self.baud
            )));
        }
        options.link.serial.baud = self.baud;
        // One reply is capped in memory (docs/io-timeouts.md): the transports refuse a longer one.
        options.link.max_message_bytes = super::bounded::MAX_REPLY_BYTES;
        Ok(options)
    }

    /// The total a one-shot command of `exchanges` commands may take (see `bounded`).
    pub fn budget(&self, exchanges: usize) -> anyhow::Result<super::bounded::Budget> {
        let options = self.session_options()?;
        let t = options.link.timeouts;
        Ok(super::bounded::Budget::new(
            t.connect,
            t.read,
            exchanges,
            t.min_rate_bytes_per_s,
        ))
    }

    /// Parses the address, opens the journal if asked, connects.
    pub async fn open(&self, global: &super::global::Global) -> anyhow::Result<Session> {
        let resource: Resource = self.address.parse()?;
        let journal = match &global.trace_io {
            Some(path) => Some(Journal::create(path, self.trace_io_keep_binary)?),
            None => None,
        };
        let mut options = self.session_options()?;
        if let Resource::Serial { .. } = resource {
            options.line = serial_line_protocol(&resource, &options).await?;
        }
        Ok(Session::open(resource, options, journal, "").await?)
    }
}

/// Which protocol a serial device speaks. A module of the catalog with a line protocol (the
/// Gotmic modules) answers every request with one line, framed with its CRC-8 once the module has
/// CRC on; a SCPI device answers queries only. Asked with `*IDN?`: a catalog identity with a line
/// protocol, or the line protocol's own refusal (`ERR ...`, e.g. a module with CRC on that wants
/// the request framed), selects it.
async fn serial_line_protocol(
    resource: &Resource,
    options: &SessionOptions,
) -> anyhow::Result<Option<radbench::session::LineProtocol>> {
    let catalog = radbench::catalog::Catalog::embedded()?;
    let line_models = || {
        catalog
            .models()
            .filter(|(m, _)| m.protocol.is_some())
            .filter_map(|(m, _)| m.protocol.as_ref())
    };
    let as_protocol = |p: &radbench::catalog::LineProtocol| radbench::session::LineProtocol {
        crc: Some(radbench::session::Crc8 {
            poly: p.crc_poly,
            init: p.crc_init,
        }),
    };
    let mut probe = Session::open(resource.clone(), options.clone(), None, "").await?;
    let reply = probe.query("*IDN?").await;
    let _ = probe.close().await;
    let Ok(reply) = reply else {
        return Ok(None);
    };
    if let Some(found) = catalog.identify(&reply) {
        return Ok(found.model.protocol.as_ref().map(as_protocol));
    }
    if reply.trim_start().starts_with("ERR ") {
        return Ok(line_models().next().map(as_protocol));
    }
    Ok(None)
}

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub connect: ConnectArgs,
    /// Commands to send in order; a command ending in `?` reads a reply. Without commands, an
    /// interactive prompt opens (type \help there).
    #[arg(value_name = "COMMAND")]
    pub commands: Vec<String>,
    /// Save every block reply (definite or indefinite, however short, text or not) and every
    /// binary reply to this file; with several, the 2nd goes to FILE.2 and so on.
    #[arg(long, value_name = "FILE")]
    pub save_binary: Option<PathBuf>,
    /// Read the error queue after every command and fail if the instrument refused something.
    /// The default for instruments of the catalog (identified by `*IDN?`), whose queue is known;
    /// this flag asks it of any instrument (SYST:ERR?, or CMR? over VICP).
    #[arg(long, conflicts_with = "no_check_errors")]
    pub check_errors: bool,
    /// Do not read the error queue (not before the first command, not after any).
    #[arg(long)]
    pub no_check_errors: bool,
}

/// How long the identity probe that decides the default error check may wait.
const PROBE_TIMEOUT: Duration = Duration::from_secs(2);

/// Whether to check errors when neither flag was given: the instrument is one of the catalog's,
/// whose error queue is known. An instrument that does not answer `*IDN?` within
/// [`PROBE_TIMEOUT`] (or the reply timeout, if shorter) is not checked.
async fn known_to_keep_errors(session: &mut Session) -> bool {
    if session.answers_every_request() {
        // A line-protocol device refuses in its reply: nothing to read afterwards.
        return false;
    }
    let Ok(catalog) = radbench::catalog::Catalog::embedded() else {
        return false;
    };
    let timeouts = &mut session.link_options_mut().timeouts;
    let read = timeouts.read;
    timeouts.read = read.min(PROBE_TIMEOUT);
    let reply = session.query("*IDN?").await;
    session.link_options_mut().timeouts.read = read;
    match reply {
        Ok(idn) => catalog
            .identify(session::without_idn_header(&idn))
            .is_some(),
        Err(_) => {
            // A late reply must not be taken for the first command's.
            let _ = session.device_clear().await;
            false
        }
    }
}

/// Empties the error queue before the first command, so an error an earlier session left is not
/// blamed on this one; says what it held.
async fn clear_earlier_errors(session: &mut Session) -> anyhow::Result<()> {
    let earlier = session.errors().await?;
    if !earlier.is_empty() {
        let list: Vec<String> = earlier.iter().map(|e| e.to_string()).collect();
        eprintln!(
            "note: the error queue held {} entr{} from before these commands (cleared, not \
             theirs): {}",
            earlier.len(),
            if earlier.len() == 1 { "y" } else { "ies" },
            list.join("; ")
        );
    }
    Ok(())
}

pub(crate) fn run(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    let runtime = super::global::runtime()?;
    if !args.commands.is_empty() {
        return runtime.block_on(one_shot_bounded(&args, global));
    }
    // Long blocks show a bar on stderr (only on a terminal).
    let bar = TransferBar::new();
    // Connecting, the identity probe and emptying the error queue: one exchange's total.
    let budget = args.connect.budget(1)?;
    let (mut session, check_errors) =
        runtime.block_on(budget.run(&args.connect.address, async {
            let mut session = args.connect.open(global).await?;
            session.link_options_mut().progress = Some(budget.counting(Some(bar.callback())));
            let check_errors = match (args.check_errors, args.no_check_errors) {
                (_, true) => false,
                (true, _) => true,
                _ => known_to_keep_errors(&mut session).await,
            };
            if check_errors {
                if let Err(e) = clear_earlier_errors(&mut session).await {
                    let _ = session.close().await;
                    return Err(e);
                }
            }
            anyhow::Ok((session, check_errors))
        }))?;
    let mut saver = BinarySaver::new(args.save_binary.clone());
    let result = interactive(
        &runtime,
        &mut session,
        &args.connect,
        &mut saver,
        check_errors,
        &bar,
    );
    let _ = runtime.block_on(session.close());
    result
}

/// The commands of the command line, the whole exchange bounded in total (see `bounded`).
async fn one_shot_bounded(args: &Args, global: &super::global::Global) -> anyhow::Result<()> {
    let budget = args.connect.budget(args.commands.len())?;
    let bar = TransferBar::new();
    let mut saver = BinarySaver::new(args.save_binary.clone());
    let work = async {
        let mut session = args.connect.open(global).await?;
        // Long blocks show a bar on stderr (only on a terminal); every byte read earns time.
        session.link_options_mut().progress = Some(budget.counting(Some(bar.callback())));
        let check_errors = match (args.check_errors, args.no_check_errors) {
            (_, true) => false,
            (true, _) => true,
            _ => known_to_keep_errors(&mut session).await,
        };
        let result = async {
            if check_errors {
                clear_earlier_errors(&mut session).await?;
            }
            one_shot(&mut session, &args.commands, &mut saver, check_errors, &bar).await
        }
        .await;
        let _ = session.close().await;
        result
    };
    let result = budget.run(&args.connect.address, work).await;
    bar.finish();
    result
}

/// Sends the commands in order and prints the replies. When standard output is closed early
/// (`| head`), the remaining commands are still sent, their replies not shown: a sequence that
/// switches something on and then off again is never cut in the middle by the reader leaving.
async fn one_shot(
    session: &mut Session,
    commands: &[String],
    saver: &mut BinarySaver,
    check_errors: bool,
    bar: &TransferBar,
) -> anyhow::Result<()> {
    let mut stdout_open = true;
    for command in commands {
        let output = execute(session, command, saver, check_errors).await;
        bar.finish();
        if let (Some(text), true) = (output?, stdout_open) {
            match out(&text) {
                Ok(()) => {}
                Err(e) if is_stdout_closed(&e) => stdout_open = false,
                Err(e) => return Err(e),
            }
        }
    }
    Ok(())
}

/// Numbers saved binary replies: FILE, FILE.2, FILE.3...
struct BinarySaver {
    path: Option<PathBuf>,
    count: usize,
}

impl BinarySaver {
    fn new(path: Option<PathBuf>) -> Self {
        Self { path, count: 0 }
    }

    fn save(&mut self, payload: &[u8]) -> anyhow::Result<Option<PathBuf>> {
        let Some(base) = &self.path else {
            return Ok(None);
        };
        self.count += 1;
        let path = if self.count == 1 {
            base.clone()
        } else {
            let mut p = base.as_os_str().to_owned();
            p.push(format!(".{}", self.count));
            PathBuf::from(p)
        };
        radbench::storage::write_atomic(&path, payload)
            .with_context(|| format!("cannot save the binary reply to {}", path.display()))?;
        Ok(Some(path))
    }
}

/// Whether a command reads a reply: one of its `;`-separated parts has a header ending in `?`
/// (possibly followed by query parameters, as in `C1:WF? ALL` or `:TRAC1:DATA? 1,0,128`).
pub(crate) fn expects_reply(command: &str) -> bool {
    command.split(';').any(|part| {
        part.split_whitespace()
            .next()
            .is_some_and(|header| header.ends_with('?'))
    })
}

/// The block of a reply, when it holds one: a `#<digit>` outside quoted strings (488.2 response
/// data has no other use for it), definite or indefinite, at any length.
fn block_of(raw: &Bytes) -> Option<session::Block> {
    let mut quoted = false;
    let start = raw.windows(2).position(|w| {
        if w[0] == b'"' {
            quoted = !quoted;
        }
        !quoted && w[0] == b'#' && w[1].is_ascii_digit()
    })?;
    let block = session::parse_block(raw.clone()).ok()?;
    (block.prefix().len() == start).then_some(block)
}

/// Describes a reply for the terminal: the text, or a summary of a block or binary reply (with
/// the bytes to save). Everything returned is safe to print: control characters are escaped.
pub(crate) fn describe_reply(raw: &Bytes) -> (String, Option<Bytes>) {
    if let Some(block) = block_of(raw) {
        let form = match block.form {
            session::BlockForm::Definite => "definite",
            session::BlockForm::Indefinite => "indefinite",
        };
        let prefix = printable_bytes(block.prefix());
        let payload = block.into_payload();
        let head: Vec<String> = payload
            .iter()
            .take(16)
            .map(|b| format!("{b:02x}"))
            .collect();
        let mut text = format!(
            "{}binary block ({form}): {} bytes, sha256 {}, first bytes: {}",
            if prefix.is_empty() {
                String::new()
            } else {
                format!("{prefix} ")
            },
            payload.len(),
            transport::sha256_hex(&payload),
            head.join(" ")
        );
        if let Some(short) = short_text(&payload) {
            text.push_str(&format!(", text \"{}\"", printable(short)));
        }
        return (text, Some(payload));
    }
    if let Some(text) = looks_like_text(raw) {
        return (printable(session::trim_reply(text)).into_owned(), None);
    }
    let head: Vec<String> = raw.iter().take(16).map(|b| format!("{b:02x}")).collect();
    (
        format!(
            "binary reply: {} bytes, sha256 {}, first bytes: {}",
            raw.len(),
            transport::sha256_hex(raw),
            head.join(" ")
        ),
        Some(raw.clone()),
    )
}

/// The reply as text when it reads as text: UTF-8 without NUL, at most one character in eight a
/// control character (an escape sequence in a message); those are shown escaped.
fn looks_like_text(raw: &[u8]) -> Option<&str> {
    let text = std::str::from_utf8(raw).ok()?;
    let mut chars = 0usize;
    let mut controls = 0usize;
    for c in text.chars() {
        chars += 1;
        if c == '\0' {
            return None;
        }
        if c.is_control() && !matches!(c, '\n' | '\r' | '\t') {
            controls += 1;
        }
    }
    (controls * 8 <= chars).then_some(text)
}

/// A block payload short and plain enough to show as text as well.
fn short_text(payload: &[u8]) -> Option<&str> {
    let text = std::str::from_utf8(payload).ok()?;
    (payload.len() <= 64 && !text.chars().any(char::is_control)).then_some(text)
}

/// Sends one command; returns what to print.
async fn execute(
    session: &mut Session,
    command: &str,
    saver: &mut BinarySaver,
    check_errors: bool,
) -> anyhow::Result<Option<String>> {
    let command = command.trim();
    if command.is_empty() {
        return Ok(None);
    }
    let mut output = None;
    if expects_reply(command) || session.answers_every_request() {
        let raw = session.query_raw(command).await?;
        let (mut text, binary) = describe_reply(&raw);
        if let Some(payload) = binary {
            if let Some(path) = saver.save(&payload)? {
                text.push_str(&format!("\nsaved to {}", path.display()));
            }
        }
        output = Some(text);
    } else {
        session.write(command).await?;
    }
    if check_errors {
        session.check_errors(Some(command)).await?;
    }
    Ok(output)
}

const HELP: &str = "\
Type SCPI commands; a command ending in `?` prints the reply.
Ctrl-C while a command runs abandons it and clears the device; the session stays open.
  \\clear        device clear
  \\stb          status byte
  \\errors       drain the error queue (SYST:ERR?)
  \\reconnect    reopen the connection
  \\timeout S    set the reply timeout to S seconds
  \\quit         leave (Ctrl-D too)";

fn history_path() -> Option<PathBuf> {
    std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".radbench_scpi_history"))
}

fn interactive(
    runtime: &tokio::runtime::Runtime,
    session: &mut Session,
    connect: &ConnectArgs,
    saver: &mut BinarySaver,
    check_errors: bool,
    bar: &TransferBar,
) -> anyhow::Result<()> {
    let mut editor = rustyline::DefaultEditor::new().context("cannot start the prompt")?;
    // Commands piped in (`radbench scpi ADDR < script`) are not typed history.
    let typed = std::io::stdin().is_terminal();
    let history = typed.then(history_path).flatten();
    if let Some(h) = &history {
        let _ = editor.load_history(h);
    }
    let prompt = format!("{}> ", printable(&session.resource().to_string()));
    eprintln!(
        "connected to {}; \\help for help",
        printable(&session.resource().to_string())
    );
    loop {
        let line = match editor.readline(&prompt) {
            Ok(line) => line,
            // Ctrl-C at the prompt drops the line being typed, as in a shell.
            Err(rustyline::error::ReadlineError::Interrupted) => {
                eprintln!("(\\quit or Ctrl-D to leave)");
                continue;
            }
            Err(rustyline::error::ReadlineError::Eof) => break,
            Err(e) => return Err(e).context("prompt failed"),
        };
        let line = line.trim().to_string();
        if line.is_empty() {
            continue;
        }
        if typed {
            let _ = editor.add_history_entry(line.as_str());
        }
        if let Some(h) = &history {
            // Written at once: no way of leaving (a signal, a lost terminal) loses it.
            let _ = editor.append_history(h);
        }
        // Each line one exchange's total, with the reply timeout as `\timeout` left it.
        let t = session.link_options_mut().timeouts;
        let budget = Budget::new(t.connect, t.read, 1, t.min_rate_bytes_per_s);
        session.link_options_mut().progress = Some(budget.counting(Some(bar.callback())));
        let what = connect.address.clone();
        let step = runtime.block_on(async {
            // Listening for Ctrl-C starts before the command is sent.
            let interrupt = interrupted();
            let line = Line {
                text: &line,
                check_errors,
                budget: &budget,
                what: &what,
            };
            line_or_cancel(session, line, saver, interrupt).await
        });
        bar.finish();
        let shown = match step {
            Step::Done(Ok(Some(Flow::Quit))) => break,
            Step::Done(Ok(Some(Flow::Print(text)))) => out(&text),
            Step::Done(Ok(None)) => Ok(()),
            Step::Done(Err(e)) => {
                report(&e);
                Ok(())
            }
            Step::Cancelled(Ok(())) => {
                eprintln!("cancelled; the device was cleared");
                Ok(())
            }
            Step::Cancelled(Err(e)) => {
                report(&e.context("cancelled, but the device clear failed"));
                Ok(())
            }
            Step::GaveUp(e, cleared) => {
                report(&e);
                match cleared {
                    Ok(()) => eprintln!("(the device was cleared; the session stays open)"),
                    Err(e) => report(&e.context("the device clear failed too: \\reconnect")),
                }
                Ok(())
            }
        };
        if let Err(e) = shown {
            // Nowhere to show replies any more: leave as if the user had.
            if is_stdout_closed(&e) {
                break;
            }
            return Err(e);
        }
    }
    Ok(())
}

/// Resolves when the user presses Ctrl-C (SIGINT) while a command runs. The handler is
/// installed here, before the command is sent, so a Ctrl-C right after it cannot fall through
/// to the default action (which would kill the process with the reply pending).
fn interrupted() -> impl Future<Output = ()> {
    use tokio::signal::unix::{signal, SignalKind};
    let listener = signal(SignalKind::interrupt());
    async move {
        match listener {
            Ok(mut sigint) => {
                sigint.recv().await;
            }
            // No signal handling: never interrupted.
            Err(_) => std::future::pending::<()>().await,
        }
    }
}

fn report(e: &anyhow::Error) {
    eprintln!("error: {}", printable(&radbench::exit::render(e)));
    if let Some(SessionError::Link { source, .. }) = e.downcast_ref::<SessionError>() {
        if matches!(source, radbench::transport::LinkError::Closed { .. }) {
            eprintln!("(the connection is gone: \\reconnect to reopen it)");
        }
    }
}

/// How one line at the prompt ended.
enum Step {
    /// It ran to its end.
    Done(anyhow::Result<Option<Flow>>),
    /// `interrupt` fired first: the line was abandoned and the device cleared (the result).
    Cancelled(anyhow::Result<()>),
    /// It passed its total (why), was abandoned and the device cleared (the result).
    GaveUp(anyhow::Error, anyhow::Result<()>),
}

/// One line at the prompt and its total.
struct Line<'a> {
    text: &'a str,
    check_errors: bool,
    budget: &'a Budget,
    /// The resource, for the give-up's message.
    what: &'a str,
}

/// Runs one prompt line within its budget unless `interrupt` fires first. An abandoned line's
/// unfinished exchange is dropped (the link knows it is mid-message and recovers) and the
/// device is cleared, so the instrument drops the command and its late reply, and the session
/// goes on. The clear is bounded too (`--timeout + 2 s`).
async fn line_or_cancel(
    session: &mut Session,
    line: Line<'_>,
    saver: &mut BinarySaver,
    interrupt: impl Future<Output = ()>,
) -> Step {
    let finished = {
        let work = line.budget.run_or_give_up(
            line.what,
            interactive_line(session, line.text, saver, line.check_errors),
        );
        tokio::pin!(work);
        tokio::pin!(interrupt);
        tokio::select! {
            result = &mut work => Some(result),
            () = &mut interrupt => None,
        }
    };
    match finished {
        Some(Ok(result)) => Step::Done(result),
        Some(Err(gave_up)) => Step::GaveUp(gave_up, bounded_clear(session).await),
        None => Step::Cancelled(bounded_clear(session).await),
    }
}

/// A device clear within the reply timeout and the margin.
async fn bounded_clear(session: &mut Session) -> anyhow::Result<()> {
    let wait = session.link_options_mut().timeouts.read + super::bounded::MARGIN;
    match tokio::time::timeout(wait, session.device_clear()).await {
        Ok(done) => Ok(done?),
        Err(_) => Err(anyhow::anyhow!(
            "no answer to the device clear within {:.1} s",
            wait.as_secs_f64()
        )),
    }
}

enum Flow {
    Print(String),
    Quit,
}

async fn interactive_line(
    session: &mut Session,
    line: &str,
    saver: &mut BinarySaver,
    check_errors: bool,
) -> anyhow::Result<Option<Flow>> {
    let Some(meta) = line.strip_prefix('\\') else {
        return Ok(execute(session, line, saver, check_errors)
            .await?
            .map(Flow::Print));
    };
    let mut words = meta.split_whitespace();
    let text = match (words.next().unwrap_or(""), words.next()) {
        ("quit" | "q" | "exit", _) => return Ok(Some(Flow::Quit)),
        ("help" | "h" | "?", _) => HELP.to_string(),
        ("clear", _) => {
            session.device_clear().await?;
            "device cleared".into()
        }
        ("stb", _) => {
            let stb = session.read_stb().await?;
            format!("status byte {stb} (0x{stb:02x}, binary {stb:08b})")
        }
        ("errors", _) => {
            let errors = session.errors().await?;
            if errors.is_empty() {
                "no errors".into()
            } else {
                errors
                    .iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join("\n")
            }
        }
        ("reconnect", _) => {
            session.reconnect().await?;
            "reconnected".into()
        }
        ("timeout", Some(value)) => {
            let secs: f64 = value.parse().map_err(|_| {
                radbench::exit::bad_input(format!("\\timeout {value}: give seconds, e.g. 5"))
            })?;
            session.link_options_mut().timeouts.read = seconds(secs, "timeout")?;
            format!("reply timeout {secs} s")
        }
        (other, _) => format!("unknown command \\{other}\n{HELP}"),
    };
    Ok(Some(Flow::Print(text)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queries_are_recognised() {
        assert!(expects_reply("*IDN?"));
        assert!(expects_reply("C1:WF? ALL"));
        assert!(expects_reply(":TRAC1:DATA? 1,0,128"));
        assert!(expects_reply("*RST;*OPC?"));
        assert!(expects_reply("*IDN?;*RST"));
        assert!(!expects_reply("*RST"));
        assert!(!expects_reply(":SOUR:FREQ 1E9"));
        assert!(!expects_reply("VBS 'app.x = \"?\"'"));
    }

    #[test]
    fn binary_replies_are_summarised() {
        let raw = Bytes::from([&b"#210"[..], &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9], b"\n"].concat());
        let (text, payload) = describe_reply(&raw);
        assert!(text.contains("10 bytes"), "{text}");
        assert!(text.contains("00 01 02"), "{text}");
        assert_eq!(payload.unwrap().len(), 10);
        let (text, payload) = describe_reply(&Bytes::from_static(b"1.5E+09\n"));
        assert_eq!(text, "1.5E+09");
        assert!(payload.is_none());
    }

    #[test]
    fn every_block_is_a_block_however_short_or_printable() {
        for (raw, form, payload) in [
            (&b"#15hello\n"[..], "definite", &b"hello"[..]),
            (b"#10\n", "definite", b""),
            (b"#0hi there\n", "indefinite", b"hi there"),
            (b"ALL,#13a\nb\n", "definite", b"a\nb"),
        ] {
            let (text, saved) = describe_reply(&Bytes::copy_from_slice(raw));
            assert!(text.contains(&format!("({form})")), "{text}");
            assert_eq!(saved.as_deref(), Some(payload), "{text}");
        }
        let (text, _) = describe_reply(&Bytes::from_static(b"#15hello\n"));
        assert!(text.ends_with("text \"hello\""), "{text}");
        // A `#<digit>` inside a quoted string is text, not a block.
        let (text, saved) = describe_reply(&Bytes::from_static(b"-113,\"Undefined header #10\"\n"));
        assert_eq!(text, "-113,\"Undefined header #10\"");
        assert!(saved.is_none());
    }

    #[test]
    fn instrument_text_is_shown_escaped() {
        let (text, saved) = describe_reply(&Bytes::from_static(b"OK\rFAIL\n"));
        assert_eq!(text, "OK\\x0dFAIL");
        assert!(saved.is_none());
        // Escape sequences in text are shown escaped; mostly control bytes make a binary reply.
        let (text, saved) = describe_reply(&Bytes::from_static(b"\x1b]0;pwned by text\x07\n"));
        assert_eq!(text, "\\x1b]0;pwned by text\\x07");
        assert!(saved.is_none());
        let (text, saved) = describe_reply(&Bytes::from_static(b"\x1b\x1b\x07\x01ab\n"));
        assert!(text.starts_with("binary reply: 7 bytes"), "{text}");
        assert!(!text.contains('\x1b'));
        assert!(saved.is_some());
        let (text, _) = describe_reply(&Bytes::from_static(b"a\0b\n"));
        assert!(text.starts_with("binary reply"), "{text}");
        let (text, _) = describe_reply(&Bytes::from_static(b"\x1b[31m,#13\x1b[m\n"));
        assert!(!text.contains('\x1b'), "{text}");
    }

    #[test]
    fn baud_zero_is_bad_input() {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            connect: ConnectArgs,
        }
        for baud in ["0", "12000001"] {
            let cli = Cli::parse_from(["x", "ASRL/dev/ttyUSB0::INSTR", "--baud", baud]);
            let err = cli.connect.session_options().unwrap_err();
            assert_eq!(
                radbench::classify(&err),
                radbench::exit::ExitClass::BadInput
            );
            assert!(err.to_string().contains("--baud"), "{err}");
        }
        let cli = Cli::parse_from(["x", "ASRL/dev/ttyUSB0::INSTR", "--baud", "9600"]);
        assert_eq!(
            cli.connect.session_options().unwrap().link.serial.baud,
            9600
        );
    }

    /// The Ctrl-C path with the signal replaced by a timer: a query the instrument sits on is
    /// abandoned, the device cleared, and the next query gets its own answer, not the late one.
    #[test]
    fn an_interrupted_command_is_abandoned_and_the_session_goes_on() {
        use mock_lab::emulator::loopback::Loopback;
        use mock_lab::server::launch::{self, Ports, Transport};
        use mock_lab::server::ServerOptions;
        let runtime = crate::cli::global::runtime().unwrap();
        runtime.block_on(async {
            for transport in [Transport::Raw, Transport::Hislip, Transport::Vxi11] {
                let (_server, endpoint) = launch::start(
                    "loopback",
                    std::sync::Arc::new(Loopback::new()),
                    transport,
                    Ports::default(),
                    ServerOptions::default(),
                )
                .await
                .unwrap();
                let resource: Resource = endpoint.resource.parse().unwrap();
                let mut session = Session::open(resource, SessionOptions::default(), None, "")
                    .await
                    .unwrap();
                let mut saver = BinarySaver::new(None);
                let limit = Duration::from_secs(20);
                let budget = Budget::new(Duration::ZERO, Duration::from_secs(120), 1, 1);
                let line = |text| Line {
                    text,
                    check_errors: false,
                    budget: &budget,
                    what: "x",
                };
                let step = tokio::time::timeout(
                    limit,
                    line_or_cancel(
                        &mut session,
                        line("SLOW? 60000"),
                        &mut saver,
                        tokio::time::sleep(Duration::from_millis(200)),
                    ),
                )
                .await
                .expect("cancelled well before the 60 s reply");
                assert!(matches!(step, Step::Cancelled(Ok(()))), "{transport:?}");
                let step = tokio::time::timeout(
                    limit,
                    line_or_cancel(
                        &mut session,
                        line("*IDN?"),
                        &mut saver,
                        std::future::pending(),
                    ),
                )
                .await
                .unwrap();
                let Step::Done(Ok(Some(Flow::Print(text)))) = step else {
                    panic!("{transport:?}: *IDN? after the cancel did not answer");
                };
                assert_eq!(
                    text,
                    mock_lab::emulator::loopback::IDENTITY,
                    "{transport:?}"
                );
            }
        });
        // A raw socket has no device clear: the emulator's SLOW? thread sleeps on; do not wait.
        runtime.shutdown_background();
    }
}
