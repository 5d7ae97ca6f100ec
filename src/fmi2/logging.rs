//! Messages to the importer through its logger callback, filtered by the
//! categories declared in modelDescription.xml.

use std::ffi::CString;

use super::types::{fmi2CallbackLogger, fmi2ComponentEnvironment, Status};

/// The log categories this FMU declares, with their descriptions.
pub const CATEGORIES: [(&str, &str); 6] = [
    ("logEvents", "Impacts, chatter ends, sticking and release, with their exact times"),
    ("logStatusWarning", "Messages with status fmi2Warning"),
    ("logStatusDiscard", "Messages with status fmi2Discard"),
    ("logStatusError", "Messages with status fmi2Error: what was wrong and what is allowed"),
    ("logStatusFatal", "Messages with status fmi2Fatal"),
    ("logAll", "Each call that changes the instance state"),
];

pub struct Logger {
    callback: fmi2CallbackLogger,
    environment: fmi2ComponentEnvironment,
    instance_name: CString,
    /// One flag per entry of `CATEGORIES`.
    enabled: [bool; CATEGORIES.len()],
}

// The environment pointer is the importer's, only handed back to its logger.
unsafe impl Send for Logger {}

fn index(category: &str) -> Option<usize> {
    CATEGORIES.iter().position(|(c, _)| *c == category)
}

impl Logger {
    pub fn new(callback: fmi2CallbackLogger, environment: fmi2ComponentEnvironment, instance_name: &str, on: bool) -> Self {
        Logger {
            callback,
            environment,
            instance_name: CString::new(instance_name.replace('\0', "")).unwrap_or_default(),
            enabled: [on; CATEGORIES.len()],
        }
    }

    pub fn instance_name(&self) -> &str {
        self.instance_name.to_str().unwrap_or("")
    }

    /// fmi2SetDebugLogging: `categories` empty means all of them.
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
                    return Err(format!("fmi2SetDebugLogging: unknown log category {c:?}; known: {}", known.join(", ")));
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
    /// standard expects the logger to have explained any fmi2Error),
    /// the rest only when their category is enabled.
    pub fn status(&self, status: Status, message: &str) {
        let category = Self::category_for(status);
        if status >= Status::Error || self.wants(category) {
            self.emit(status, category, message);
        }
    }

    /// Logs in a category if it is enabled.
    pub fn category(&self, category: &str, message: &str) {
        if self.wants(category) {
            self.emit(Status::Ok, category, message);
        }
    }

    fn emit(&self, status: Status, category: &str, message: &str) {
        let Some(callback) = self.callback else { return };
        // The logger takes a printf format: escape '%'.
        let text = CString::new(message.replace('%', "%%").replace('\0', "")).unwrap_or_default();
        let cat = CString::new(category).unwrap_or_default();
        // SAFETY: the importer promised a valid logger for the instance's
        // lifetime; every pointer passed is a valid NUL-terminated string.
        unsafe { callback(self.environment, self.instance_name.as_ptr(), status.raw(), cat.as_ptr(), text.as_ptr()) };
    }
}
