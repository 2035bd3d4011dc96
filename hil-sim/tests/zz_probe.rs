#![allow(clippy::unwrap_used)]
use hil_sim::faults::{Case, Matrix};
use hil_sim::sim::Injection;
use std::sync::atomic::AtomicBool;
#[test]
fn probe() {
    let d = drive_file::DriveFile::shipped().unwrap();
    let mut m = Matrix::new(d.spec, d.certify.unwrap().omega_r_max_rad_s, 310.0);
    let c = d.board.unwrap().table.comparator.unwrap();
    m.comparator = Some(hil_sim::bridge_fault::Comparator { trip_a: c.trip_a, filter_s: c.filter_s });
    for phase in 0..3 {
        for upper in [true, false] {
            let case = Case { name: "sw", injection: Injection::SwitchOpen { phase, upper } };
            for at in m.points() {
                let o = m.run_one(7, &case, &at, m.expect(&case, &at), &AtomicBool::new(false)).unwrap();
                println!(
                    "ph {phase} up {upper} {:28} {:40} peak {:.2}",
                    at.name(),
                    o.seen(),
                    o.peak_current_a
                );
            }
        }
    }
}
