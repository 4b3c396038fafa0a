//! The checklist: one line per check ([`Check`], its [`Status`]), written in order by the check
//! groups into a [`List`], handed out as the [`Report`].

use serde::Serialize;

/// How one check came out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Pass,
    /// Holds, but worth a look (not a failure: the exit code stays 0).
    Warn,
    Fail,
    /// Not checked, because something it needs failed first.
    Skip,
}

impl Status {
    pub fn mark(self) -> &'static str {
        match self {
            Status::Pass => "ok",
            Status::Warn => "WARN",
            Status::Fail => "FAIL",
            Status::Skip => "skip",
        }
    }
}

/// One line of the checklist.
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// A stable name, e.g. `scope.remote_interface`.
    pub id: String,
    pub status: Status,
    /// What was found.
    pub detail: String,
    /// What to do about it (failures and warnings).
    pub fix: Option<String>,
}

/// The whole checklist.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub bench: String,
    pub checks: Vec<Check>,
    /// True when no check failed.
    pub ok: bool,
}

/// The checklist as the groups write it, in the order they run.
#[derive(Default)]
pub(super) struct List(Vec<Check>);

impl List {
    fn push(&mut self, id: impl Into<String>, status: Status, detail: impl Into<String>) {
        self.0.push(Check {
            id: id.into(),
            status,
            detail: detail.into(),
            fix: None,
        });
    }

    pub(super) fn pass(&mut self, id: impl Into<String>, detail: impl Into<String>) {
        self.push(id, Status::Pass, detail);
    }

    pub(super) fn skip(&mut self, id: impl Into<String>, detail: impl Into<String>) {
        self.push(id, Status::Skip, detail);
    }

    fn bad(
        &mut self,
        id: impl Into<String>,
        status: Status,
        detail: impl Into<String>,
        fix: impl Into<String>,
    ) {
        self.0.push(Check {
            id: id.into(),
            status,
            detail: detail.into(),
            fix: Some(fix.into()),
        });
    }

    pub(super) fn fail(
        &mut self,
        id: impl Into<String>,
        detail: impl Into<String>,
        fix: impl Into<String>,
    ) {
        self.bad(id, Status::Fail, detail, fix);
    }

    pub(super) fn warn(
        &mut self,
        id: impl Into<String>,
        detail: impl Into<String>,
        fix: impl Into<String>,
    ) {
        self.bad(id, Status::Warn, detail, fix);
    }

    /// The report of `bench`: every check, `ok` when none failed.
    pub(super) fn into_report(self, bench: String) -> Report {
        let ok = self.0.iter().all(|c| c.status != Status::Fail);
        Report {
            bench,
            checks: self.0,
            ok,
        }
    }
}
