//! `radbench scpi ADDRESS [COMMAND ...]`: sends SCPI commands one-shot, or at an interactive prompt
//! with history when no command is given. A command ending in `?` reads a reply; binary replies are
//! summarised (length, SHA-256, first bytes) and can be saved with `--save-binary`.

use super::progress::TransferBar;
use crate::address::Resource;
use crate::session::{reply, Session, SessionError, SessionOptions};
use crate::transport::{journal, Journal, Timeouts};
use anyhow::Context;
use bytes::Bytes;
use std::path::{Path, PathBuf};
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
    /// Serial speed for ASRL resources.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
}

fn seconds(value: f64, flag: &str) -> anyhow::Result<Duration> {
    if value.is_finite() && value > 0.0 && value <= 86_400.0 {
        Ok(Duration::from_secs_f64(value))
    } else {
        Err(crate::exit::bad_input(format!(
            "--{flag} {value}: give a number of seconds between 0 and 86400"
        )))
    }
}

impl ConnectArgs {
    pub fn session_options(&self) -> anyhow::Result<SessionOptions> {
        if !(self.min_rate.is_finite() && self.min_rate > 0.0) {
            return Err(crate::exit::bad_input(format!(
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
        options.link.serial.baud = self.baud;
        Ok(options)
    }

    /// Parses the address, opens the journal if asked, connects.
    pub async fn open(&self, global: &super::Global) -> anyhow::Result<Session> {
        let resource: Resource = self.address.parse()?;
        let journal = match &global.trace_io {
            Some(path) => Some(Journal::create(path, self.trace_io_keep_binary)?),
            None => None,
        };
        let mut options = self.session_options()?;
        if let Resource::Serial { .. } = resource {
            options.line = Some(serial_line_protocol()?);
        }
        Ok(Session::open(resource, options, journal, "").await?)
    }
}

/// The serial instruments of the catalog are the Gotmic modules: every request gets one reply
/// line, framed with the catalog's CRC-8 once the module has CRC on.
fn serial_line_protocol() -> anyhow::Result<crate::session::LineProtocol> {
    let catalog = crate::catalog::Catalog::embedded()?;
    let crc = catalog
        .models()
        .filter(|(m, _)| {
            m.transports
                .iter()
                .any(|t| t.kind == crate::catalog::TransportKind::Serial)
        })
        .find_map(|(m, _)| m.protocol.as_ref())
        .map(|p| crate::session::Crc8 {
            poly: p.crc_poly,
            init: p.crc_init,
        });
    Ok(crate::session::LineProtocol { crc })
}

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub connect: ConnectArgs,
    /// Commands to send in order; a command ending in `?` reads a reply. Without commands, an
    /// interactive prompt opens (type \help there).
    #[arg(value_name = "COMMAND")]
    pub commands: Vec<String>,
    /// Save binary (block) replies to this file; with several, the 2nd goes to FILE.2 and so on.
    #[arg(long, value_name = "FILE")]
    pub save_binary: Option<PathBuf>,
    /// Drain SYST:ERR? after every command and fail if the instrument refused something.
    #[arg(long)]
    pub check_errors: bool,
}

pub fn run(args: Args, global: &super::Global) -> anyhow::Result<()> {
    let runtime = super::runtime()?;
    let mut session = runtime.block_on(args.connect.open(global))?;
    // Long blocks show a bar on stderr (only on a terminal).
    let bar = TransferBar::new();
    session.link_options_mut().progress = Some(bar.callback());
    let mut saver = BinarySaver::new(args.save_binary.clone());
    let result = if args.commands.is_empty() {
        interactive(&runtime, &mut session, &mut saver, args.check_errors, &bar)
    } else {
        runtime.block_on(async {
            for command in &args.commands {
                let output = execute(&mut session, command, &mut saver, args.check_errors).await;
                bar.finish();
                let output = output?;
                if let Some(text) = output {
                    println!("{text}");
                }
            }
            anyhow::Ok(())
        })
    };
    let _ = runtime.block_on(session.close());
    result
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
        write_atomically(&path, payload)
            .with_context(|| format!("cannot save the binary reply to {}", path.display()))?;
        Ok(Some(path))
    }
}

/// Writes to a temporary file beside `path`, then renames it over `path`.
fn write_atomically(path: &Path, data: &[u8]) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".part");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, data)?;
    std::fs::rename(&tmp, path)
}

/// Whether a command reads a reply: one of its `;`-separated parts has a header ending in `?`
/// (possibly followed by query parameters, as in `C1:WF? ALL` or `:TRAC1:DATA? 1,0,128`).
pub fn expects_reply(command: &str) -> bool {
    command.split(';').any(|part| {
        part.split_whitespace()
            .next()
            .is_some_and(|header| header.ends_with('?'))
    })
}

/// Describes a reply for the terminal: the text, or a summary of a binary block.
pub fn describe_reply(raw: &Bytes) -> (String, Option<Bytes>) {
    let is_text = std::str::from_utf8(raw).is_ok_and(|t| {
        t.chars()
            .all(|c| !c.is_control() || matches!(c, '\n' | '\r' | '\t'))
    });
    if let Ok(block) = reply::parse_block(raw.clone()) {
        if !is_text || block.len() > 64 {
            let payload = block.clone().into_payload();
            let form = match block.form {
                reply::BlockForm::Definite => "definite",
                reply::BlockForm::Indefinite => "indefinite",
            };
            let prefix = String::from_utf8_lossy(block.prefix()).to_string();
            let head: Vec<String> = payload
                .iter()
                .take(16)
                .map(|b| format!("{b:02x}"))
                .collect();
            let text = format!(
                "{}binary block ({form}): {} bytes, sha256 {}, first bytes: {}",
                if prefix.is_empty() {
                    String::new()
                } else {
                    format!("{prefix} ")
                },
                payload.len(),
                journal::sha256_hex(&payload),
                head.join(" ")
            );
            return (text, Some(payload));
        }
    }
    if is_text {
        let text = String::from_utf8_lossy(raw);
        return (reply::trim_reply(&text).to_string(), None);
    }
    let head: Vec<String> = raw.iter().take(16).map(|b| format!("{b:02x}")).collect();
    (
        format!(
            "binary reply: {} bytes, sha256 {}, first bytes: {}",
            raw.len(),
            journal::sha256_hex(raw),
            head.join(" ")
        ),
        Some(raw.clone()),
    )
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
    saver: &mut BinarySaver,
    check_errors: bool,
    bar: &TransferBar,
) -> anyhow::Result<()> {
    let mut editor = rustyline::DefaultEditor::new().context("cannot start the prompt")?;
    let history = history_path();
    if let Some(h) = &history {
        let _ = editor.load_history(h);
    }
    let prompt = format!("{}> ", session.resource());
    eprintln!("connected to {}; \\help for help", session.resource());
    loop {
        let line = match editor.readline(&prompt) {
            Ok(line) => line,
            Err(rustyline::error::ReadlineError::Interrupted)
            | Err(rustyline::error::ReadlineError::Eof) => break,
            Err(e) => return Err(e).context("prompt failed"),
        };
        let line = line.trim().to_string();
        if line.is_empty() {
            continue;
        }
        let _ = editor.add_history_entry(line.as_str());
        let outcome = runtime.block_on(interactive_line(session, &line, saver, check_errors));
        bar.finish();
        match outcome {
            Ok(Some(Flow::Quit)) => break,
            Ok(Some(Flow::Print(text))) => println!("{text}"),
            Ok(None) => {}
            Err(e) => {
                eprintln!("error: {}", crate::exit::render(&e));
                if let Some(SessionError::Link { source, .. }) = e.downcast_ref::<SessionError>() {
                    if matches!(source, crate::transport::LinkError::Closed { .. }) {
                        eprintln!("(the connection is gone: \\reconnect to reopen it)");
                    }
                }
            }
        }
    }
    if let Some(h) = &history {
        let _ = editor.save_history(h);
    }
    Ok(())
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
                crate::exit::bad_input(format!("\\timeout {value}: give seconds, e.g. 5"))
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
}
