//! `radbench idn ADDRESS`: asks an instrument who it is (`*IDN?`) and prints the parsed identity.

use super::scpi::ConnectArgs;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub connect: ConnectArgs,
    /// Print the identity as JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args, global: &super::Global) -> anyhow::Result<()> {
    let runtime = super::runtime()?;
    runtime.block_on(async {
        let mut session = args.connect.open(global).await?;
        let identity = session.idn().await;
        let _ = session.close().await;
        let identity = identity?;
        if args.json {
            println!("{}", serde_json::to_string_pretty(&identity)?);
        } else {
            println!("manufacturer: {}", identity.manufacturer);
            println!("model:        {}", identity.model);
            println!("serial:       {}", identity.serial);
            println!("firmware:     {}", identity.firmware);
        }
        Ok(())
    })
}
