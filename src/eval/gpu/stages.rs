//! The WGSL of the effect stages that is generated from the model
//! description: every realisation's parameter struct (from the catalogue's
//! parameter lists), and, for the realisations a model has, the loads of
//! their parameters and the calls of their stages in the catalogue's step
//! order ([`STEP_ORDER`]), as `stages!` generates `Prepared::step`'s calls
//! on the CPU. `shaders/effects.wgsl` holds each realisation's stage, named
//! by the rule of [`WgslName`], and the step that calls what this
//! generates.

use crate::model::effects::{Effect, ModelDescription, Param, Params, STEP_ORDER, Side};

/// The WGSL names of a realisation's stage, from its variant's name (which
/// is its CPU stage's type, `stages::creep::TwoPoleCreep`): the types
/// `TwoPoleCreepParams` (generated here), `TwoPoleCreepConsts` and
/// `TwoPoleCreepState`, the functions `two_pole_creep_prepare`,
/// `two_pole_creep_start`, `two_pole_creep_step` and
/// `two_pole_creep_restart` (in `shaders/effects.wgsl`), and the private
/// variables `two_pole_creep_consts` and `two_pole_creep_state` (generated
/// here).
pub struct WgslName {
    /// The variant's name: `TwoPoleCreep`.
    pub ty: String,
    /// Its snake case: `two_pole_creep`.
    pub snake: String,
}

impl WgslName {
    pub fn of(effect: Effect) -> WgslName {
        let ty = format!("{effect:?}");
        let mut snake = String::with_capacity(ty.len() + 4);
        for (i, c) in ty.chars().enumerate() {
            if c.is_ascii_uppercase() && i > 0 {
                snake.push('_');
            }
            snake.push(c.to_ascii_lowercase());
        }
        WgslName { ty, snake }
    }
}

/// The generated part of the effect step for `model`: the parameter
/// structs of every realisation (so that every stage of
/// `shaders/effects.wgsl` compiles in every pipeline), the private
/// variables holding the constants and states of the realisations `model`
/// has, and the functions `shaders/effects.wgsl`'s `score` calls:
/// `stages_prepare` (loads each realisation's parameters from the
/// candidate's row and derives its constants), `stages_start`,
/// `stages_input`, `stages_state`, `stages_output` (the sides of the step,
/// each realisation's stage in the step order) and `stages_restart` (each
/// realisation's restart term, in the step order).
pub fn source(model: &ModelDescription) -> String {
    let mut out = String::new();
    for e in Effect::ALL {
        out.push_str(&params_struct(e));
    }
    let present: Vec<_> = STEP_ORDER
        .iter()
        .filter(|placed| model.offset_of(placed.effect).is_some())
        .collect();
    for placed in &present {
        let WgslName { ty, snake } = WgslName::of(placed.effect);
        out.push_str(&format!("var<private> {snake}_consts: {ty}Consts;\n"));
        if placed.stateful {
            out.push_str(&format!("var<private> {snake}_state: {ty}State;\n"));
        }
    }

    let mut prepare = String::new();
    let mut start = String::new();
    let (mut input, mut state, mut output) = (String::new(), String::new(), String::new());
    let mut restart = String::new();
    for placed in &present {
        let e = placed.effect;
        let WgslName { ty, snake } = WgslName::of(e);
        let at = model.offset_of(e).expect("present");
        prepare.push_str(&format!("    var {snake}_params: {ty}Params;\n"));
        match e.entry().params {
            Params::Fixed(list) => {
                for (j, Param { name, .. }) in list.iter().enumerate() {
                    prepare.push_str(&format!("    {snake}_params.{name} = params[p + {}u];\n", at + j));
                }
            }
            // Dataset 0 is the reference: its parameter is 0.
            Params::PerLaterDataset { name, .. } => prepare.push_str(&format!(
                "    if (frame.e >= 1u) {{\n        {snake}_params.{name} = params[p + {at}u + frame.e - 1u];\n    }}\n"
            )),
        }
        prepare.push_str(&format!(
            "    {snake}_consts = {snake}_prepare({snake}_params, frame);\n"
        ));
        let state_arg = if placed.stateful {
            start.push_str(&format!(
                "    {snake}_state = {snake}_start({snake}_consts, x, u0);\n"
            ));
            restart.push_str(&format!("    x = {snake}_restart(&{snake}_state, y, x);\n"));
            format!("&{snake}_state, ")
        } else {
            String::new()
        };
        let call = format!("{snake}_step({snake}_consts, {state_arg}");
        match placed.side {
            Side::Input => input.push_str(&format!("    v = {call}v, at);\n")),
            Side::State => state.push_str(&format!("    {call}xk, a_eff, at);\n")),
            Side::Output => output.push_str(&format!("    v = {call}v, ui, xk, at);\n")),
        }
    }
    out.push_str(&format!(
        "\nfn stages_prepare(p: u32, frame: Frame) {{\n{prepare}}}\n\n\
         fn stages_start(x: f32, u0: f32) {{\n{start}}}\n\n\
         fn stages_input(ui: f32, at: At) -> f32 {{\n    var v = ui;\n{input}    return v;\n}}\n\n\
         fn stages_state(xk: ptr<function, f32>, a_eff: ptr<function, f32>, at: At) {{\n{state}}}\n\n\
         fn stages_output(y: f32, ui: f32, xk: f32, at: At) -> f32 {{\n    var v = y;\n{output}    return v;\n}}\n\n\
         fn stages_restart(y: f32) -> f32 {{\n    var x = y;\n{restart}    return x;\n}}\n"
    ));
    out
}

/// `effect`'s parameter struct: a field per parameter of the catalogue's
/// list, named as there (the load gains once: `g`, the experiment's own).
fn params_struct(effect: Effect) -> String {
    let names: Vec<&str> = match effect.entry().params {
        Params::Fixed(list) => list.iter().map(|p| p.name).collect(),
        Params::PerLaterDataset { name, .. } => vec![name],
    };
    let fields: String = names.iter().map(|n| format!("    {n}: f32,\n")).collect();
    format!("struct {}Params {{\n{fields}}}\n", WgslName::of(effect).ty)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Family;

    #[test]
    fn names_follow_the_cpu_stages() {
        let name = WgslName::of(Effect::TwoPoleCreep);
        assert_eq!(
            (name.ty.as_str(), name.snake.as_str()),
            ("TwoPoleCreep", "two_pole_creep")
        );
        assert_eq!(WgslName::of(Effect::Delay).snake, "delay");
        assert_eq!(
            WgslName::of(Effect::OnOffThreshold).snake,
            "on_off_threshold"
        );
    }

    #[test]
    fn the_step_order_places_every_realisation_once_with_its_states() {
        for e in Effect::ALL {
            assert_eq!(
                STEP_ORDER.iter().filter(|p| p.effect == e).count(),
                1,
                "{e}"
            );
        }
        let placed = |e| *STEP_ORDER.iter().find(|p| p.effect == e).unwrap();
        // The dead zone carries no state, the play its output; the rate
        // moves the stiffness on the state side.
        assert!(!placed(Effect::Deadzone).stateful);
        assert!(placed(Effect::Backlash).stateful);
        assert_eq!(placed(Effect::Rate).side, Side::State);
        assert_eq!(placed(Effect::OutputLag).side, Side::Output);
    }

    #[test]
    fn only_the_present_stages_are_called_in_the_step_order() {
        // Listed out of the step order: the calls follow the step order.
        let model = ModelDescription::new(
            Family::Classic,
            vec![Effect::OutputLag, Effect::Deadzone, Effect::Load],
            3,
        );
        let src = source(&model);
        // Classic has 9 parameters: the output lag's pole is the 10th, the
        // dead zone's threshold the 11th, the load gains the 12th and 13th.
        assert!(
            src.contains("    output_lag_params.rho = params[p + 9u];\n"),
            "{src}"
        );
        assert!(
            src.contains("    deadzone_params.p0 = params[p + 10u];\n"),
            "{src}"
        );
        assert!(
            src.contains("load_params.g = params[p + 11u + frame.e - 1u];"),
            "{src}"
        );
        let input = src.split("fn stages_input").nth(1).unwrap();
        let (dz, load) = (input.find("deadzone_step"), input.find("load_step"));
        assert!(dz.unwrap() < load.unwrap(), "{input}");
        assert!(!src.contains("creep_step"), "{src}");
        // Only the lag carries states; it restarts.
        assert!(src.contains("var<private> output_lag_state: OutputLagState;"));
        assert!(!src.contains("deadzone_state"));
        assert!(src.contains("x = output_lag_restart(&output_lag_state, y, x);"));
        // Every realisation's parameters have their struct.
        for e in Effect::ALL {
            assert!(src.contains(&format!("struct {}Params {{", WgslName::of(e).ty)));
        }
    }
}
