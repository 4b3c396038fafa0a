//! The M8195A command tree: manual-style header patterns mapped to commands.
//!
//! Why a hand-written table and not the `scpi` crate: the crate's tree cannot hand a numeric suffix
//! to the handler (`TRAC2` needs its own node, and the handler cannot tell which one matched), its
//! error queue and common commands live in another crate, and the emulator must answer with this
//! instrument's own error texts. A pattern table over [`Pattern`] keeps long/short forms, optional
//! nodes, suffixes and the compound-header rule in ~200 tested lines.

use crate::emulator::scpi::header::Pattern;

/// A command of the M8195A tree (suffixed ones carry their channel at dispatch time).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    DacMode,
    ExtRateDivider,
    MemoryMode,
    Raster,
    FunctionMode,
    InitContinuous,
    InitGate,
    InitImmediate,
    Abort,
    TraceDefine,
    TraceData,
    TraceCatalog,
    TraceDelete,
    TraceDeleteAll,
    TraceSelect,
    TraceFree,
    Amplitude,
    Offset,
    High,
    Low,
    Output,
    SystemError,
    SystemErrorCount,
    RefSource,
    RefFrequency,
}

/// Which forms a command accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Forms {
    SetAndQuery,
    SetOnly,
    QueryOnly,
}

/// `(pattern, command, forms)` for the whole tree.
pub const TREE: &[(&str, Command, Forms)] = &[
    (":INSTrument:DACMode", Command::DacMode, Forms::SetAndQuery),
    (
        ":INSTrument:MEMory:EXTended:RDIVider",
        Command::ExtRateDivider,
        Forms::SetAndQuery,
    ),
    (":TRACe#:MMODe", Command::MemoryMode, Forms::SetAndQuery),
    (
        "[:SOURce]:FREQuency:RASTer",
        Command::Raster,
        Forms::SetAndQuery,
    ),
    (
        "[:SOURce]:FUNCtion:MODE",
        Command::FunctionMode,
        Forms::SetAndQuery,
    ),
    (
        ":INITiate:CONTinuous[:STATe]",
        Command::InitContinuous,
        Forms::SetAndQuery,
    ),
    (
        ":INITiate:GATE[:STATe]",
        Command::InitGate,
        Forms::SetAndQuery,
    ),
    (
        ":INITiate[:IMMediate]",
        Command::InitImmediate,
        Forms::SetOnly,
    ),
    (":ABORt", Command::Abort, Forms::SetOnly),
    (":TRACe#:DEFine", Command::TraceDefine, Forms::SetOnly),
    (":TRACe#:DATA", Command::TraceData, Forms::SetAndQuery),
    (":TRACe#:CATalog", Command::TraceCatalog, Forms::QueryOnly),
    (":TRACe#:DELete", Command::TraceDelete, Forms::SetOnly),
    (
        ":TRACe#:DELete:ALL",
        Command::TraceDeleteAll,
        Forms::SetOnly,
    ),
    (":TRACe#:SELect", Command::TraceSelect, Forms::SetAndQuery),
    (":TRACe#:FREE", Command::TraceFree, Forms::QueryOnly),
    (
        "[:SOURce]:VOLTage#[:LEVel][:IMMediate][:AMPLitude]",
        Command::Amplitude,
        Forms::SetAndQuery,
    ),
    (
        "[:SOURce]:VOLTage#[:LEVel][:IMMediate]:OFFSet",
        Command::Offset,
        Forms::SetAndQuery,
    ),
    (
        "[:SOURce]:VOLTage#[:LEVel][:IMMediate]:HIGH",
        Command::High,
        Forms::QueryOnly,
    ),
    (
        "[:SOURce]:VOLTage#[:LEVel][:IMMediate]:LOW",
        Command::Low,
        Forms::QueryOnly,
    ),
    (":OUTPut#[:STATe]", Command::Output, Forms::SetAndQuery),
    (
        ":SYSTem:ERRor[:NEXT]",
        Command::SystemError,
        Forms::QueryOnly,
    ),
    (
        ":SYSTem:ERRor:COUNt",
        Command::SystemErrorCount,
        Forms::QueryOnly,
    ),
    (
        "[:SOURce]:ROSCillator:SOURce",
        Command::RefSource,
        Forms::SetAndQuery,
    ),
    (
        "[:SOURce]:ROSCillator:FREQuency",
        Command::RefFrequency,
        Forms::SetAndQuery,
    ),
];

/// The tree with its patterns parsed once.
pub fn compiled() -> Vec<(Pattern, Command, Forms)> {
    TREE.iter()
        .map(|(p, c, f)| (Pattern::new(p), *c, *f))
        .collect()
}
