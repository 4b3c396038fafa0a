//! One query to an instrument on a fresh session, bounded: for `doctor --verify-catalog`, which
//! asks for values the drivers never need (`*OPT?`). A fresh session per query keeps an
//! unanswered query from putting the next one out of step.

use super::error::{session, DriverError};
use super::io::open_session;
use crate::address::Resource;
use crate::catalog::InstrumentModel;
use crate::transport::Journal;
use std::time::Duration;

/// The reply to `query` (its terminator removed), or why there is none: an error, or no answer
/// within `limit` (connecting included).
pub(crate) async fn ask_once(
    resource: Resource,
    model: &InstrumentModel,
    query: &str,
    limit: Duration,
    journal: Option<Journal>,
    name: &str,
) -> Result<String, String> {
    let work = async {
        let mut s = open_session(resource, model, "", journal, name)
            .await
            .map_err(session(name))?;
        s.query(query).await.map_err(session(name))
    };
    match tokio::time::timeout(limit, work).await {
        Ok(Ok(reply)) => Ok(reply.trim().to_string()),
        Ok(Err(e)) => Err(DriverError::to_string(&e)),
        Err(_) => Err(format!(
            "no answer to {query} within {}",
            crate::transport::Rounded(limit)
        )),
    }
}
