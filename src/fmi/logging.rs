//! Messages to the importer through its logger callback, filtered by the
//! categories declared in modelDescription.xml. The callback's shape is
//! the shell's ([`Sink`]); the filtering is shared.

use super::state::Status;

/// The log categories this FMU declares, with their descriptions (`{fmi}`
/// stands for the standard's prefix, fmi2 or fmi3: see `xml::log_categories`).
pub const CATEGORIES: [(&str, &str); 6] = [
    ("logEvents", "Impacts, chatter ends, sticking and release, with their exact times"),
    ("logStatusWarning", "Messages with status {fmi}Warning"),
    ("logStatusDiscard", "Messages with status {fmi}Discard"),
    ("logStatusError", "Messages with status {fmi}Error: what was wrong and what is allowed"),
    ("logStatusFatal", "Messages with status {fmi}Fatal"),
    ("logAll", "Each call that changes the instance state"),
];

/// The importer's logger callback, as one standard calls it.
pub trait Sink: Send {
    fn emit(&self, status: Status, category: &str, message: &str);
}

pub struct Logger {
    sink: Box<dyn Sink>,
    /// One flag per entry of `CATEGORIES`.
    enabled: [bool; CATEGORIES.len()],
}

fn index(category: &str) -> Option<usize> {
    CATEGORIES.iter().position(|(c, _)| *c == category)
}

impl Logger {
    pub fn new(sink: Box<dyn Sink>, on: bool) -> Self {
        Logger { sink, enabled: [on; CATEGORIES.len()] }
    }

    /// SetDebugLogging: `categories` empty means all of them.
    pub fn set_categories(&mut self, on: bool, categories: &[String]) -> Result<(), String> {
        if categories.is_empty() {
            self.enabled = [on; CATEGORIES.len()];
            return Ok(());
        }
        let mut indices = Vec::new();
        for c in categories {
            match index(c) {
                Some(i) => indices.push(i),
                None => {
                    let known: Vec<&str> = CATEGORIES.iter().map(|(c, _)| *c).collect();
                    return Err(format!("unknown log category {c:?}; known: {}", known.join(", ")));
                }
            }
        }
        for i in indices {
            self.enabled[i] = on;
        }
        Ok(())
    }

    fn category_for(status: Status) -> &'static str {
        match status {
            Status::Ok => "logAll",
            Status::Warning => "logStatusWarning",
            Status::Discard => "logStatusDiscard",
            Status::Error => "logStatusError",
            Status::Fatal => "logStatusFatal",
        }
    }

    /// Whether a message of this category would reach the importer (each
    /// category is switched on and off by itself).
    pub fn wants(&self, category: &str) -> bool {
        index(category).is_some_and(|i| self.enabled[i])
    }

    /// Logs a status message: errors always reach the importer (the
    /// standard expects the logger to have explained any Error), the rest
    /// only when their category is enabled.
    pub fn status(&self, status: Status, message: &str) {
        let category = Self::category_for(status);
        if status >= Status::Error || self.wants(category) {
            self.sink.emit(status, category, message);
        }
    }

    /// Logs in a category if it is enabled.
    pub fn category(&self, category: &str, message: &str) {
        if self.wants(category) {
            self.sink.emit(Status::Ok, category, message);
        }
    }
}
