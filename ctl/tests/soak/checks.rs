//! The checks on the whole run, once QEMU has ended: each returns what it found wrong, in words.

use feeder_shared::protocol::Param;
use feeder_shared::{Drive, Limits, TickClock, TickPlan, Waveform};
use host_sim::contact::Contact;
use host_sim::hil::{self, CheckReport, EdgeTimes};

use crate::log::{Plan, Summary};
use crate::operator::{echo_tolerance, Parameters};

/// Every edge the shared scheduler planned, none more, none different, no amplitude change
/// inside a cycle, and every request applied at the first cycle boundary after the control loop
/// took it (the replay applies it there; a late or early change shows as differing edges).
pub fn edges(report: &CheckReport) -> Result<(), String> {
    if report.passed() {
        return Ok(());
    }
    let mut found = format!(
        "edge check: {} edges, {} missing, {} unexpected, {} glitches",
        report.edges, report.missing, report.unexpected, report.glitches
    );
    for problem in &report.problems {
        found.push_str("\n    ");
        found.push_str(problem);
    }
    Err(found)
}

/// The firmware logged no error, every event line was readable, and the checker's replay of
/// them ran to the end.
pub fn log_lines(summary: &Summary) -> Result<(), String> {
    let mut found = Vec::new();
    found.extend(
        summary
            .checker_panic
            .iter()
            .map(|panic| format!("the checker's replay on the shared scheduler panicked: {panic}")),
    );
    found.extend(
        summary
            .firmware_errors
            .iter()
            .map(|line| format!("firmware error: {line}")),
    );
    found.extend(
        summary
            .unreadable
            .iter()
            .map(|line| format!("unreadable event: {line}")),
    );
    if found.is_empty() {
        Ok(())
    } else {
        Err(found.join("\n  "))
    }
}

pub fn motion_cycles(report: &CheckReport, target: u64) -> Result<(), String> {
    if report.motion_cycles >= target {
        Ok(())
    } else {
        Err(format!(
            "the run had {} motion cycles, not the {target} asked for",
            report.motion_cycles
        ))
    }
}

/// The plans the control loop reported after the power-up plan are the accepted changes
/// (`set`, `recipe load`) in order, with the parameters their replies stated, except those a
/// newer change replaced in the mailbox before the control loop took them; the last accepted
/// change always runs. Returns how many changes were replaced.
pub fn changes_applied(accepted: &[Parameters], plans: &[Plan]) -> Result<usize, String> {
    let reported = plans.get(1..).unwrap_or_default();
    let mut matched = 0;
    let mut last_ran = false;
    for change in accepted {
        last_ran = reported
            .get(matched)
            .is_some_and(|plan| same_parameters(change, plan));
        if last_ran {
            matched += 1;
        }
    }
    if matched < reported.len() {
        return Err(format!(
            "the control loop ran a plan no accepted change asked for, in that order: {:?} \
             (plan {} of {} after power-up; {} changes accepted)",
            reported[matched],
            matched + 1,
            reported.len(),
            accepted.len()
        ));
    }
    if !accepted.is_empty() && !last_ran {
        return Err(format!(
            "the last accepted change {:?} never ran ({} changes accepted, {} plans reported)",
            accepted.last(),
            accepted.len(),
            reported.len()
        ));
    }
    Ok(accepted.len() - reported.len())
}

fn same_parameters(reply: &Parameters, plan: &Plan) -> bool {
    let close = |param: Param, stated: f64, planned: f64| {
        (stated - planned).abs() <= echo_tolerance(param, stated)
    };
    let amplitude = match plan.spec.drive {
        Drive::Stroke { stroke_m } => close(Param::Stroke, reply.stroke_mm, stroke_m * 1e3),
        Drive::Accel { accel_mps2 } => close(Param::Accel, reply.accel_mps2, accel_mps2),
    };
    amplitude
        && close(Param::Frequency, reply.freq_hz, 1.0 / plan.spec.period_s)
        && close(Param::Duty, reply.duty, plan.spec.duty)
        && reply.ramp_cycles == plan.ramp_cycles
}

/// How far the plate strayed on the planned ticks, and how far it may.
pub struct Drift {
    /// Largest distance from its start at any cycle boundary.
    pub worst_m: f64,
    /// The largest drift bound of the plans run.
    pub bound_m: f64,
    /// Half a residual unit per plan change: the scheduler carries its displacement residual
    /// into each new plan's units, rounded.
    pub rounding_m: f64,
}

/// The plate simulated on the planned ticks stays, at every cycle boundary, within the largest
/// drift bound of the plans it ran, plus the rounding at each plan change.
pub fn drift(summary: &Summary) -> Result<Drift, String> {
    let tick_plans = summary
        .plans
        .iter()
        .map(tick_plan)
        .collect::<Result<Vec<_>, _>>()?;
    let bound_m = tick_plans
        .iter()
        .map(|plan| plan.drift_bound_m)
        .fold(0.0, f64::max);
    let rounding_m: f64 = tick_plans
        .iter()
        .skip(1)
        .map(|plan| plan.residual_unit_m() / 2.0)
        .sum();
    // The part does not move the plate; any contact will do.
    let contact = Contact::kinetic(0.3, 1e-4).map_err(|error| error.to_string())?;
    let planned = hil::simulate(
        &summary.edges,
        summary.clock_hz,
        &contact,
        EdgeTimes::Planned,
    );
    let mut position_m = 0.0_f64;
    let mut worst_m = 0.0_f64;
    for cycle in &planned.cycles {
        position_m += cycle.plate_velocity_mps * cycle.duration_s;
        worst_m = worst_m.max(position_m.abs());
    }
    let drift = Drift {
        worst_m,
        bound_m,
        rounding_m,
    };
    if worst_m <= bound_m + rounding_m {
        Ok(drift)
    } else {
        Err(format!(
            "on the planned ticks the plate strayed {worst_m:e} m from its start, beyond the \
             plans' drift bound {bound_m:e} m + {rounding_m:e} m of rounding"
        ))
    }
}

fn tick_plan(plan: &Plan) -> Result<TickPlan, String> {
    Waveform::new(plan.spec, &Limits::NONE)
        .and_then(|waveform| TickPlan::new(&waveform, TickClock::new(plan.clock_hz)))
        .map_err(|error| format!("plan {plan:?} cannot be replanned: {error}"))
}
