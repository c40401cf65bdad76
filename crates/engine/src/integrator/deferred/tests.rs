use super::*;
use glam::DVec3;

fn buffered(answers: &Answers) -> BufferedPoints<'_> {
    BufferedPoints {
        answers,
        picks: false,
        picks_emission: false,
        missing: RefCell::default(),
        used: RefCell::default(),
        complete: Cell::new(true),
        gave_up: Cell::new(false),
        last: Cell::new(None),
    }
}

#[test]
fn keys_tell_apart_every_bit_of_a_request() {
    let r = Request { p: DVec3::new(1.5, -2.0, 3.25), ask: Ask::DensityPicked, u: 0.375 };
    let next = |v: f64| f64::from_bits(v.to_bits() + 1);
    let others = [
        Request { p: DVec3::new(next(1.5), -2.0, 3.25), ..r },
        Request { p: DVec3::new(1.5, next(-2.0), 3.25), ..r },
        Request { p: DVec3::new(1.5, -2.0, next(3.25)), ..r },
        Request { u: next(0.375), ..r },
        Request { ask: Ask::Density, ..r },
        Request { ask: Ask::EmissionPicked, ..r },
        Request { p: DVec3::new(-2.0, 1.5, 3.25), ..r },
    ];
    assert_eq!(r.key(), Request { ..r }.key());
    for o in others {
        assert_ne!(r.key(), o.key(), "{o:?}");
    }
}

#[test]
fn buffered_points_serve_what_was_answered_and_note_the_rest() {
    let (p, q) = (DVec3::new(1.0, 2.0, 3.0), DVec3::new(1.0, 2.0, 3.5));
    let mut answers = Answers::default();
    answers.entries.push((Request { p, ask: Ask::Density, u: 0.0 }.key(), [0.5, 0.25, 0.0]));
    answers.entries.push((Request { p: q, ask: Ask::Emission, u: 0.0 }.key(), [1.0, 2.0, 3.0]));
    answers.sort();
    let b = buffered(&answers);
    assert_eq!(b.density(p), 0.5);
    // A real collision at the tentative point: its albedo came with the density
    assert_eq!(b.albedo(p), 0.25);
    assert_eq!(b.emission(q), [1.0, 2.0, 3.0]);
    assert!(b.complete.get() && b.missing.borrow().is_empty());
    // The answers read, by index (the albedo came with the density: not read again)
    let (at_p, at_q) = (
        answers.get(Request { p, ask: Ask::Density, u: 0.0 }.key()),
        answers.get(Request { p: q, ask: Ask::Emission, u: 0.0 }.key()),
    );
    assert_eq!(*b.used.borrow(), [at_p.unwrap().0 as u32, at_q.unwrap().0 as u32]);
    // Another ask at an answered point, a picked read, an albedo elsewhere: missing
    assert_eq!(b.emission(p), [0.0; 3]);
    assert_eq!(b.density_picked(p, 0.5), 0.0);
    assert_eq!(b.albedo(q), 0.0);
    assert!(!b.complete.get());
    let asks: Vec<Ask> = b.missing.borrow().iter().map(|r| r.ask).collect();
    assert_eq!(asks, [Ask::Emission, Ask::DensityPicked, Ask::Albedo]);
    assert!(!b.gave_up.get());
    // A recorded segment: answered only if every request is
    let b = buffered(&answers);
    assert!(b.has_all(&[
        Request { p, ask: Ask::Density, u: 0.0 },
        Request { p: q, ask: Ask::Emission, u: 0.0 }
    ]));
    assert!(b.complete.get());
    assert!(!b.has_all(&[
        Request { p, ask: Ask::Density, u: 0.0 },
        Request { p: q, ask: Ask::Density, u: 0.0 }
    ]));
    assert!(!b.complete.get() && b.missing.borrow().len() == 1);
    // The point estimator's whole record is never served: the path goes direct
    let b = buffered(&answers);
    let _ = b.sample(p, true);
    assert!(b.gave_up.get() && !b.complete.get());
}

#[test]
fn answers_keep_one_value_per_key() {
    let mut answers = Answers::default();
    let r = Request { p: DVec3::ONE, ask: Ask::Emission, u: 0.0 };
    answers.entries.extend([(r.key(), [1.0; 3]), (7, [2.0; 3]), (r.key(), [1.0; 3])]);
    answers.sort();
    assert_eq!(answers.entries.len(), 2);
    assert_eq!(answers.get(r.key()).map(|a| a.1), Some([1.0; 3]));
    assert_eq!(answers.get(7).map(|a| a.1), Some([2.0; 3]));
    assert_eq!(answers.get(8), None);
}

/// A path resumed from a later collision keeps only the values read after it.
#[test]
fn answers_keep_the_entries_read() {
    let mut answers = Answers::default();
    answers.entries.extend((0..5u32).map(|k| (u128::from(k) * 10, [f64::from(k); 3])));
    answers.keep(&[3, 1, 3]);
    assert_eq!(answers.entries, [(10, [1.0; 3]), (30, [3.0; 3])]);
    assert_eq!(answers.get(30), Some((1, [3.0; 3])));
    answers.keep(&[]);
    assert!(answers.entries.is_empty());
}
