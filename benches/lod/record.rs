//! One measurement of the lod bench (a method, a tolerance's choice or a peer on one
//! scene and pass) and the scene it was measured on.

use matedit::lod::{Choice, Method};
use matedit::{Image, Scene};
use serde_json::{Value, json};

use crate::common::median;
use crate::errors::worst;

/// One measurement: a method (or a tolerance's choice, or a peer) on one scene, one pass.
pub struct Rec {
    pub scene: String,
    pub env: String,
    pub material: String,
    /// The method's name (the chosen one for a tolerance; `peer-NAME` for a peer).
    pub method: String,
    pub pass: &'static str,
    pub times: Vec<f64>,
    pub reps: usize,
    pub errors: Value,
    /// For a tolerance's run: the tolerance and the choice.
    pub chosen: Option<(f64, Choice)>,
    pub extra: serde_json::Map<String, Value>,
}

impl Rec {
    pub fn json(&self) -> Value {
        let mut v = json!({
            "scene": self.scene, "env": self.env, "material": self.material,
            "method": self.method, "family": family(&self.method), "pass": self.pass,
            "median_s": median(&self.times), "reps": self.reps, "times_s": self.times,
            "errors": self.errors, "err_max": worst(&self.errors),
            "chosen_by_tol": self.chosen.is_some(),
        });
        if let (Some((tol, c)), Value::Object(o)) = (&self.chosen, &mut v) {
            let e = &c.estimate;
            o.insert("tol".into(), json!(tol));
            o.insert(
                "estimate".into(),
                json!({
                    "image": e.image, "d_env": e.d_env, "d_normals": e.d_normals,
                    "d_ctrl": e.d_ctrl, "max": e.max(), "pixels": e.pixels,
                }),
            );
            o.insert("predicted_cost".into(), json!(c.cost));
            o.insert("estimate_wrong".into(), json!(worst(&self.errors) > *tol));
        }
        if let Value::Object(o) = &mut v {
            o.extend(self.extra.clone());
        }
        v
    }
}

/// The chart's grouping of a method: exact, env (blocks), env+keep, table, table+env
/// (a table over blocks, kept texels or both), cull (culling alone), or peer.
pub fn family(method: &str) -> &'static str {
    if method.starts_with("peer-") {
        return "peer";
    }
    let Ok(m) = method.parse::<Method>() else {
        return "other";
    };
    match (m.table, m.env_factor > 1 || m.keep > 0) {
        _ if m.is_exact() => "exact",
        // culling alone (beside a table or blocks, those name the family)
        (None, false) => "cull",
        (None, true) if m.keep > 0 => "env+keep",
        (None, true) => "env",
        (Some(_), false) => "table",
        (Some(_), true) => "table+env",
    }
}

/// Everything measured on one scene (normals, env, material).
pub struct Case<'a> {
    pub name: String,
    pub env: &'a str,
    pub scene: Scene,
    pub upstream: Image,
}

impl Case<'_> {
    pub fn rec(&self, method: String, pass: &'static str, times: Vec<f64>, errors: Value) -> Rec {
        Rec {
            scene: self.name.clone(),
            env: self.env.to_string(),
            material: self.scene.material.name.clone(),
            method,
            pass,
            reps: times.len(),
            times,
            errors,
            chosen: None,
            extra: serde_json::Map::new(),
        }
    }
}
