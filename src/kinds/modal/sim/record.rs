//! What a run reports: the events it met ([`Event`], [`EventKind`]) and
//! their one-line descriptions for a log.

use crate::kinds::modal::model::Model;

/// What happened at an event.
#[derive(Clone, Debug, PartialEq)]
pub enum EventKind {
    /// An impact at `stop` with approach speed `speed`; `chatter` marks the
    /// final `R = 0` impact of a chatter sequence.
    Impact { stop: usize, speed: f64, restitution: f64, energy_lost: f64, chatter: bool },
    /// The beam sticks to `stop`; `reaction` is the stop's force then.
    Stick { stop: usize, reaction: f64 },
    /// The reaction of `stop` changed sign: the beam leaves it.
    Release { stop: usize },
    /// The beam touched `stop` with zero velocity and left without impact.
    Graze { stop: usize },
    /// A compliant stop starts pushing (`speed`: the approach speed).
    Contact { stop: usize, speed: f64 },
    /// A compliant stop's force reached zero; `penetration` is left over
    /// (non-zero only with a dashpot).
    Separation { stop: usize, penetration: f64 },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Event {
    pub time: f64,
    pub kind: EventKind,
}

impl Event {
    /// The stop the event happened at.
    pub fn stop(&self) -> usize {
        match self.kind {
            EventKind::Impact { stop, .. }
            | EventKind::Stick { stop, .. }
            | EventKind::Release { stop }
            | EventKind::Graze { stop }
            | EventKind::Contact { stop, .. }
            | EventKind::Separation { stop, .. } => stop,
        }
    }

    /// One line for a log, naming the stop as the model does.
    pub fn describe(&self, model: &Model) -> String {
        let t = self.time;
        let name = model.stops[self.stop()].name.as_str();
        match &self.kind {
            EventKind::Impact { speed, restitution, energy_lost, chatter, .. } => format!(
                "t = {t:?}: impact at stop '{name}', approach speed {speed:.6e}, R = {restitution}, energy lost {energy_lost:.6e}{}",
                if *chatter { " (chatter detected: final R = 0 impact)" } else { "" }
            ),
            EventKind::Stick { reaction, .. } => format!("t = {t:?}: sticking starts at stop '{name}', reaction {reaction:.6e}"),
            EventKind::Release { .. } => format!("t = {t:?}: release from stop '{name}' (reaction changed sign)"),
            EventKind::Graze { .. } => format!("t = {t:?}: grazing contact at stop '{name}' (zero velocity, no impact)"),
            // (+ 0.0: a touch at rest reads 0, not -0.)
            EventKind::Contact { speed, .. } => format!("t = {t:?}: contact starts at stop '{name}', approach speed {:.6e}", speed + 0.0),
            EventKind::Separation { penetration, .. } => {
                format!("t = {t:?}: contact ends at stop '{name}' (force zero), penetration left {penetration:.6e}")
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinds::modal::scene::Scene;

    /// Every kind of event names its own stop, by index and, in the log
    /// line, by the name the scene gives it (two stops, the event at the
    /// second).
    #[test]
    fn every_event_names_its_stop() {
        let scene = Scene::from_json(
            r#"{
                "name": "TwoStops",
                "structure": { "type": "beam", "support": "pinned-pinned", "modes": 2 },
                "damping": { "zeta": 0.01 },
                "stops": [
                    { "name": "left_stop", "x": 0.25, "gap": 0.1, "side": "positive", "law": { "type": "restitution", "R": 0.5, "eps": 1e-6 } },
                    { "name": "right_stop", "x": 0.75, "gap": 0.1, "side": "negative", "law": { "type": "spring_dashpot", "k": 10.0, "c": 0.1 } }
                ]
            }"#,
        )
        .unwrap();
        let model = Model::build(&scene).unwrap();
        let kinds = [
            EventKind::Impact { stop: 1, speed: 0.5, restitution: 0.5, energy_lost: 0.1, chatter: true },
            EventKind::Stick { stop: 1, reaction: 2.0 },
            EventKind::Release { stop: 1 },
            EventKind::Graze { stop: 1 },
            EventKind::Contact { stop: 1, speed: 0.5 },
            EventKind::Separation { stop: 1, penetration: 1e-3 },
        ];
        for kind in kinds {
            let event = Event { time: 1.25, kind };
            assert_eq!(event.stop(), 1, "{event:?}");
            let line = event.describe(&model);
            assert!(line.starts_with("t = 1.25") && line.contains("stop 'right_stop'") && !line.contains("left_stop"), "{line}");
        }
    }
}
