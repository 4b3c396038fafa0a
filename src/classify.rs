//! From an error chain to the process exit code: each layer's error type knows its
//! [`ExitClass`]; this walks the chain and asks the first one that does. Above every layer (it
//! names each layer's error type); the binary and the Python package call it.

use crate::exit::{Classified, Classify, ExitClass};

/// Walks an error chain and returns the class of the first error that knows its class.
pub fn classify(err: &anyhow::Error) -> ExitClass {
    for cause in err.chain() {
        if let Some(c) = cause.downcast_ref::<Classified>() {
            return c.class;
        }
        if let Some(class) = registered_class(cause) {
            return class;
        }
        if cause.downcast_ref::<clap::Error>().is_some() {
            return ExitClass::BadInput;
        }
    }
    ExitClass::Internal
}

/// Layer error types register here (one line each) so their class is found in an `anyhow` chain.
fn registered_class(cause: &(dyn std::error::Error + 'static)) -> Option<ExitClass> {
    macro_rules! try_types {
        ($($t:ty),* $(,)?) => {
            $(if let Some(e) = cause.downcast_ref::<$t>() { return Some(e.exit_class()); })*
        };
    }
    try_types!(
        crate::waveform::ParamError,
        crate::waveform::DecodeError,
        crate::dsp::DspError,
        crate::address::AddressError,
        crate::transport::LinkError,
        crate::transport::JournalError,
        crate::session::SessionError,
        crate::catalog::CatalogError,
        crate::driver::DriverError,
        crate::driver::TrcError,
        crate::storage::StorageError,
        crate::storage::RecordingError,
        crate::simulate::SimError,
        crate::measure::MeasureError,
        crate::measure::BenchFileError,
        crate::campaign::CampaignError,
        crate::campaign::SpecError,
        crate::runs_db::RunsDbError,
    );
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exit::render;
    use crate::session::SessionError;
    use crate::transport::LinkError;

    #[test]
    fn render_names_each_cause_once() {
        let refused = std::io::Error::from(std::io::ErrorKind::ConnectionRefused);
        let refused_text = refused.to_string();
        let err = anyhow::Error::new(SessionError::Link {
            resource: "TCPIP::127.0.0.1::5025::SOCKET".into(),
            source: LinkError::Connect {
                target: "127.0.0.1:5025".into(),
                protocol: "SOCKET",
                source: refused,
            },
        });
        let text = render(&err);
        assert_eq!(text.matches(&refused_text).count(), 1, "{text}");
        assert!(
            text.starts_with("TCPIP::127.0.0.1::5025::SOCKET: cannot connect to 127.0.0.1:5025")
        );
        assert_eq!(classify(&err), ExitClass::Instrument);
    }

    #[test]
    fn render_keeps_context_and_new_causes() {
        let err = anyhow::Error::new(std::io::Error::other("disk full"))
            .context("cannot write run/capture.bin");
        assert_eq!(render(&err), "cannot write run/capture.bin: disk full");
    }
}
