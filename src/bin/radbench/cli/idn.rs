//! `radbench idn ADDRESS`: asks an instrument who it is (`*IDN?`) and prints the parsed identity.
//! The fields are the instrument's text: control characters in them are shown escaped.

use super::scpi::ConnectArgs;
use super::terminal::{out, printable};
use radbench::session::Identity;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub connect: ConnectArgs,
    /// Print the identity as JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

pub(crate) fn run(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    let runtime = super::global::runtime()?;
    // One exchange, bounded in total (see `bounded`).
    let budget = args.connect.budget(1)?;
    let identity = runtime.block_on(budget.run(&args.connect.address, async {
        let mut session = args.connect.open(global).await?;
        session.link_options_mut().progress = Some(budget.counting(None));
        let identity = session.idn().await;
        let _ = session.close().await;
        anyhow::Ok(identity?)
    }))?;
    if args.json {
        // JSON escapes control characters itself.
        out(&serde_json::to_string_pretty(&identity)?)
    } else {
        out(&describe(&identity))
    }
}

/// The identity as four aligned lines, safe for a terminal.
pub(crate) fn describe(identity: &Identity) -> String {
    format!(
        "manufacturer: {}\nmodel:        {}\nserial:       {}\nfirmware:     {}",
        printable(&identity.manufacturer),
        printable(&identity.model),
        printable(&identity.serial),
        printable(&identity.firmware)
    )
}
