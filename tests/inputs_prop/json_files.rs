//! Valid materials, manifests and NBRDF files as JSON, and edits to any JSON document.

use matedit::Material;
use matedit::brdf::nbrdf;
use matedit::io::{self};
use proptest::prelude::*;
use proptest::sample::{Index, select};
use serde_json::{Value, json};

use crate::mutations::value;

pub(crate) fn valid_ctrl() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(
        prop_oneof![-40.0..=40.0f64, select(&[0.0, -0.0, 40.0, -40.0][..])],
        108,
    )
    .prop_flat_map(|scales| {
        let exps = prop::collection::vec(
            prop_oneof![0.0..=1.0e4f64, select(&[0.0, 1.0e4, 5.0e-324][..])],
            108,
        );
        (Just(scales), exps)
    })
    .prop_map(|(scales, exps)| {
        (0..108)
            .map(|i| if (i / 6) % 2 == 1 { exps[i] } else { scales[i] })
            .collect()
    })
}

pub(crate) fn valid_material() -> impl Strategy<Value = Material> {
    (any::<String>(), valid_ctrl())
        .prop_map(|(name, ctrl)| Material::new(name, &ctrl).expect("a valid material"))
}

/// Any JSON value: leaves of every kind, arrays and objects up to 3 deep.
fn json_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        value().prop_map(|v| serde_json::Number::from_f64(v).map_or(Value::Null, Value::Number)),
        ".{0,8}".prop_map(Value::from),
    ];
    leaf.prop_recursive(3, 64, 8, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..8).prop_map(Value::Array),
            prop::collection::btree_map("[a-z0-9_]{0,6}", inner, 0..4)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

/// A change to a JSON document at the node reached by walking `path`: replace it, resize
/// it (an array: cut or repeat its last element) or drop one of its keys (an object).
#[derive(Clone, Debug)]
pub(crate) enum JsonEdit {
    Replace(Vec<Index>, Value),
    Resize(Vec<Index>, usize),
    DropKey(Vec<Index>, Index),
}

pub(crate) fn json_edit() -> impl Strategy<Value = JsonEdit> {
    let path = prop::collection::vec(any::<Index>(), 0..4);
    prop_oneof![
        (path.clone(), json_value()).prop_map(|(p, v)| JsonEdit::Replace(p, v)),
        (path.clone(), 0usize..300).prop_map(|(p, n)| JsonEdit::Resize(p, n)),
        (path, any::<Index>()).prop_map(|(p, k)| JsonEdit::DropKey(p, k)),
    ]
}

fn walk<'a>(v: &'a mut Value, path: &[Index]) -> &'a mut Value {
    let Some((i, rest)) = path.split_first() else {
        return v;
    };
    let len = match v {
        Value::Array(a) => a.len(),
        Value::Object(o) => o.len(),
        _ => 0,
    };
    if len == 0 {
        return v;
    }
    let k = i.index(len);
    match v {
        Value::Array(a) => walk(&mut a[k], rest),
        Value::Object(o) => walk(o.values_mut().nth(k).expect("k < len"), rest),
        _ => v,
    }
}

pub(crate) fn edit_json(mut doc: Value, e: &JsonEdit) -> Vec<u8> {
    match e {
        JsonEdit::Replace(p, new) => *walk(&mut doc, p) = new.clone(),
        JsonEdit::Resize(p, n) => {
            if let Value::Array(a) = walk(&mut doc, p) {
                let last = a.last().cloned().unwrap_or(Value::Null);
                a.resize(*n, last);
            }
        }
        JsonEdit::DropKey(p, k) => {
            if let Value::Object(o) = walk(&mut doc, p)
                && !o.is_empty()
            {
                let key = o.keys().nth(k.index(o.len())).cloned().expect("k < len");
                o.remove(&key);
            }
        }
    }
    serde_json::to_vec(&doc).expect("json")
}

pub(crate) fn material_json() -> impl Strategy<Value = Value> {
    valid_material().prop_map(|m| {
        serde_json::from_slice(&io::json::encode_material(&m, Some("d"))).expect("json")
    })
}

/// A manifest mixing valid and invalid entries of every key.
pub(crate) fn manifest_json() -> impl Strategy<Value = Value> {
    let names = matedit::presets::names();
    let preset = prop_oneof![select(names), select(&["", "no-such-preset"][..])];
    let scene = (
        select(&["out.png", "", "/abs/out.exr", "out.png", "o/x.npy"][..]),
        prop::option::of(select(&["n.npy", "n.png", "", "/abs/n.exr"][..])),
        prop::option::of(prop_oneof![
            0usize..300,
            select(&[8192, 8193, usize::MAX][..])
        ]),
        prop::option::of(select(&["sky.exr", ""][..])),
        prop::option::of(select(&["m.json"][..])),
        prop::option::of(preset),
        prop::option::of(select(&["up.npy"][..])),
    )
        .prop_map(
            |(output, normals, sphere, env, material, preset, upstream)| {
                let mut o = serde_json::Map::new();
                o.insert("output".into(), output.into());
                let opt = |o: &mut serde_json::Map<_, _>, k: &str, v: Option<Value>| {
                    if let Some(v) = v {
                        o.insert(k.into(), v);
                    }
                };
                opt(&mut o, "normals", normals.map(Value::from));
                opt(&mut o, "sphere", sphere.map(Value::from));
                opt(&mut o, "env", env.map(Value::from));
                opt(&mut o, "material", material.map(Value::from));
                opt(&mut o, "preset", preset.map(Value::from));
                opt(&mut o, "upstream", upstream.map(Value::from));
                Value::Object(o)
            },
        );
    (
        prop::collection::vec(scene, 0..4),
        prop::option::of(select(
            &["64x128", "full", "0x1", "8", "16384x16385", "3x4"][..],
        )),
        prop::option::of(select(&["equirect", "paper", "x"][..])),
        prop::option::of(select(&[40.0, 0.0, 180.0, -1.0, 1e300, 179.9][..])),
    )
        .prop_map(|(scenes, size, conv, fov)| {
            let mut o = json!({ "scenes": scenes });
            if let Some(s) = size {
                o["env_size"] = s.into();
            }
            if let Some(c) = conv {
                o["convention"] = c.into();
            }
            if let Some(f) = fov {
                o["fov"] = f.into();
            }
            o
        })
}

/// A valid NBRDF file of one or two networks.
pub(crate) fn nbrdf_json() -> impl Strategy<Value = Value> {
    let net = prop::collection::vec(-1.0..1.0f64, 6 * 21 + 21 + 21 * 21 + 21 + 21 * 3 + 3)
        .prop_map(|v| {
            let mut it = v.into_iter();
            let mut take = |r: usize, c: usize| -> Value {
                let rows: Vec<Vec<f64>> = (0..r).map(|_| it.by_ref().take(c).collect()).collect();
                if r == 1 { json!(rows[0]) } else { json!(rows) }
            };
            json!({"w1": take(6, 21), "b1": take(1, 21), "w2": take(21, 21),
                   "b2": take(1, 21), "w3": take(21, 3), "b3": take(1, 3)})
        });
    prop::collection::vec(net, 1..3).prop_map(|nets| {
        let materials: serde_json::Map<_, _> = nets
            .into_iter()
            .enumerate()
            .map(|(i, n)| (format!("m{i}"), n))
            .collect();
        json!({"format": nbrdf::FORMAT, "materials": materials})
    })
}
