//! The M8195A command tree: manual-style header patterns, each with the small functions that run
//! its command and query forms ([`handlers`](super::handlers)).
//!
//! Why a hand-written table and not the `scpi` crate: the crate's tree cannot hand a numeric suffix
//! to the handler (`TRAC2` needs its own node, and the handler cannot tell which one matched), its
//! error queue and common commands live in another crate, and the emulator must answer with this
//! instrument's own error texts. A pattern table over [`Pattern`] keeps long/short forms, optional
//! nodes, suffixes and the compound-header rule in ~200 tested lines.

use super::handlers::{self as h, Call, Get, Set};
use super::inner::Inner;
use crate::emulator::scpi::error_queue::ScpiError;
use crate::emulator::scpi::header::Pattern;

/// One node of the tree: its pattern and its forms (`None`: the form does not exist).
pub(super) struct Entry {
    pub pattern: &'static str,
    pub set: Option<Set>,
    pub query: Option<Get>,
    /// The query takes parameters (`:TRAC:DATA? id,offset,length`); others refuse any.
    pub query_params: bool,
}

const fn both(pattern: &'static str, set: Set, query: Get) -> Entry {
    Entry {
        pattern,
        set: Some(set),
        query: Some(query),
        query_params: false,
    }
}

const fn set_only(pattern: &'static str, set: Set) -> Entry {
    Entry {
        pattern,
        set: Some(set),
        query: None,
        query_params: false,
    }
}

const fn query_only(pattern: &'static str, query: Get) -> Entry {
    Entry {
        pattern,
        set: None,
        query: Some(query),
        query_params: false,
    }
}

/// The whole tree, in match order.
pub(super) const TREE: &[Entry] = &[
    both(":INSTrument:DACMode", h::set_dac_mode, h::get_dac_mode),
    both(
        ":INSTrument:MEMory:EXTended:RDIVider",
        h::set_divider,
        h::get_divider,
    ),
    both(":TRACe#:MMODe", h::set_memory_mode, h::get_memory_mode),
    Entry {
        pattern: "[:SOURce]:FREQuency:RASTer",
        set: Some(h::set_raster),
        query: Some(h::get_raster),
        // `:FREQ:RAST? MIN|MAX|DEF`: the limits, as SCPI answers them.
        query_params: true,
    },
    both(
        "[:SOURce]:FUNCtion:MODE",
        h::set_function_mode,
        h::get_function_mode,
    ),
    both(
        ":INITiate:CONTinuous[:STATe]",
        h::set_continuous,
        h::get_continuous,
    ),
    both(":INITiate:GATE[:STATe]", h::set_gate, h::get_gate),
    set_only(":INITiate[:IMMediate]", h::start),
    set_only(":ABORt", h::abort),
    set_only(":TRACe#:DEFine", h::define_segment),
    Entry {
        pattern: ":TRACe#:DATA",
        set: Some(h::write_data),
        query: Some(h::read_data),
        query_params: true,
    },
    query_only(":TRACe#:CATalog", h::get_catalog),
    set_only(":TRACe#:DELete", h::delete_segment),
    set_only(":TRACe#:DELete:ALL", h::delete_all_segments),
    both(":TRACe#:SELect", h::select_segment, h::get_selected_segment),
    query_only(":TRACe#:FREE", h::get_free),
    both(
        "[:SOURce]:VOLTage#[:LEVel][:IMMediate][:AMPLitude]",
        h::set_amplitude,
        h::get_amplitude,
    ),
    both(
        "[:SOURce]:VOLTage#[:LEVel][:IMMediate]:OFFSet",
        h::set_offset,
        h::get_offset,
    ),
    query_only("[:SOURce]:VOLTage#[:LEVel][:IMMediate]:HIGH", h::get_high),
    query_only("[:SOURce]:VOLTage#[:LEVel][:IMMediate]:LOW", h::get_low),
    both(":OUTPut#[:STATe]", h::set_output, h::get_output),
    query_only(":SYSTem:ERRor[:NEXT]", h::next_error),
    query_only(":SYSTem:ERRor:COUNt", h::error_count),
    both(
        "[:SOURce]:ROSCillator:SOURce",
        h::set_reference_source,
        h::get_reference_source,
    ),
    both(
        "[:SOURce]:ROSCillator:FREQuency",
        h::set_reference_frequency,
        h::get_reference_frequency,
    ),
];

/// The tree with its patterns parsed once.
pub(super) fn compiled() -> Vec<(Pattern, &'static Entry)> {
    TREE.iter().map(|e| (Pattern::new(e.pattern), e)).collect()
}

/// One form of a node, ready to run.
#[derive(Clone, Copy)]
pub(super) enum Form {
    Set(Set),
    /// A query and whether it takes parameters.
    Get(Get, bool),
}

impl Entry {
    /// The form a header asks for, if the node has it.
    pub(super) fn form(&self, query: bool) -> Option<Form> {
        if query {
            self.query.map(|get| Form::Get(get, self.query_params))
        } else {
            self.set.map(Form::Set)
        }
    }
}

impl Form {
    /// Runs the form; a parameter on a query that takes none is `-108`.
    pub(super) fn run(self, inner: &mut Inner, call: &Call) -> Result<Option<String>, ScpiError> {
        match self {
            Form::Set(set) => set(inner, call).map(|()| None),
            Form::Get(_, false) if !call.params.is_empty() => Err(ScpiError::new(
                -108,
                format!("{} takes no parameter", call.header),
            )),
            Form::Get(get, _) => get(inner, call).map(Some),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::TREE;

    #[test]
    fn every_node_has_a_form() {
        for e in TREE {
            assert!(e.set.is_some() || e.query.is_some(), "{}", e.pattern);
            assert!(!e.query_params || e.query.is_some(), "{}", e.pattern);
        }
    }
}
