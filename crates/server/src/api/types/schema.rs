//! Schemas the `ToSchema` derive cannot state from a Rust type alone: the
//! fixed-length arrays of the wire ([`Vec3`], [`Joints`], [`Pose`]) that
//! requests read as `Vec<f64>` (so that a wrong length is a 422 naming the
//! field, not a parse error), the free-form blocks ([`ModelCard`],
//! [`AnyJson`]), and strings whose values are a closed list
//! ([`string_enum`]). Every `openapi.yaml` schema is derived from the types
//! in [`super`], these included (`crate::api::openapi`).

use utoipa::openapi::schema::{ArrayBuilder, ObjectBuilder, Schema, SchemaType, Type};
use utoipa::openapi::{RefOr, schema::AdditionalProperties};
use utoipa::{PartialSchema, ToSchema};

/// The largest number of joints an arm may have on the wire
/// (`treemanip_core::robot::joint_vector::MAX_DOF`).
pub const MAX_DOF: usize = 8;

fn numbers(len_min: usize, len_max: usize, description: &str) -> RefOr<Schema> {
    ArrayBuilder::new()
        .items(ObjectBuilder::new().schema_type(Type::Number))
        .min_items(Some(len_min))
        .max_items(Some(len_max))
        .description(Some(description))
        .into()
}

/// A point or vector `[x, y, z]` (m, or N for a force).
pub struct Vec3;

impl PartialSchema for Vec3 {
    fn schema() -> RefOr<Schema> {
        numbers(3, 3, "[x, y, z]: m (N for a force)")
    }
}
impl ToSchema for Vec3 {}

/// A colour `[r, g, b]`, each 0-255.
pub struct Rgb;

impl PartialSchema for Rgb {
    fn schema() -> RefOr<Schema> {
        ArrayBuilder::new()
            .items(
                ObjectBuilder::new()
                    .schema_type(Type::Integer)
                    .minimum(Some(0))
                    .maximum(Some(255)),
            )
            .min_items(Some(3))
            .max_items(Some(3))
            .description(Some("[r, g, b], each 0-255"))
            .into()
    }
}
impl ToSchema for Rgb {}

/// One value per joint of an arm.
pub struct Joints;

impl PartialSchema for Joints {
    fn schema() -> RefOr<Schema> {
        numbers(
            1,
            MAX_DOF,
            "One value per joint of the robot (`GET /v1/robots`), in its `joint_names` order (rad, or m for a prismatic joint), each within its joint's limits (422 naming the joint otherwise).",
        )
    }
}
impl ToSchema for Joints {}

/// A rotation as a unit quaternion.
pub struct Quaternion;

impl PartialSchema for Quaternion {
    fn schema() -> RefOr<Schema> {
        numbers(
            4,
            4,
            "[qx, qy, qz, qw]: a rotation (normalised by the server; not all zero)",
        )
    }
}
impl ToSchema for Quaternion {}

/// A frame's pose.
pub struct Pose;

impl PartialSchema for Pose {
    fn schema() -> RefOr<Schema> {
        numbers(7, 7, "[x, y, z, qx, qy, qz, qw]: m and a unit quaternion")
    }
}
impl ToSchema for Pose {}

/// An interval [low, high].
pub struct Interval;

impl PartialSchema for Interval {
    fn schema() -> RefOr<Schema> {
        numbers(2, 2, "[low, high]")
    }
}
impl ToSchema for Interval {}

/// The models the repository ships (`models/*.onnx`, tested); a
/// deployment may serve others, which `GET /v1/models` lists.
pub const SHIPPED_MODELS: [&str; 5] = [
    "forward_path",
    "forward_gnn",
    "policy_gnn",
    "forward_pointnet",
    "policy_pointnet",
];

/// A model's name: its file's stem.
pub struct ModelName;

impl PartialSchema for ModelName {
    fn schema() -> RefOr<Schema> {
        string_enum(
            &SHIPPED_MODELS,
            Some("A model file's stem (the committed models; a deployment may serve others, GET /v1/models lists them)."),
        )
        .into()
    }
}
impl ToSchema for ModelName {}

/// The OpenAPI document itself, as a YAML mapping.
pub struct OpenApiDocument;

impl PartialSchema for OpenApiDocument {
    fn schema() -> RefOr<Schema> {
        ObjectBuilder::new()
            .schema_type(Type::Object)
            .required("openapi")
            .required("info")
            .required("paths")
            .into()
    }
}
impl ToSchema for OpenApiDocument {}

/// A model's card as `/v1/models` answers it.
pub struct ModelCard;

impl PartialSchema for ModelCard {
    fn schema() -> RefOr<Schema> {
        let object = |required: &[&str]| {
            let mut o = ObjectBuilder::new().schema_type(Type::Object);
            for r in required {
                o = o.required(*r);
            }
            o
        };
        let string = || ObjectBuilder::new().schema_type(Type::String);
        let integer = || ObjectBuilder::new().schema_type(Type::Integer);
        let number = || ObjectBuilder::new().schema_type(Type::Number);
        let nullable =
            |t: Type| ObjectBuilder::new().schema_type(SchemaType::from_iter([t, Type::Null]));
        let ints = || ArrayBuilder::new().items(integer());
        let free = || ObjectBuilder::new().schema_type(Type::Object);
        let mut card = object(&treemanip_core::model::card::KEYS)
        .description(Some(
            "The model's card, written by the exporter into the ONNX file's metadata_props (one key per field) and read back as one typed record (`crates/core/src/model/card.rs`).",
        ));
        let training_data = object(&[
            "directory",
            "dataset_seed",
            "regenerate",
            "sizes",
            "limit_per_size",
            "validation",
        ])
        .property("directory", string())
        .property("dataset_seed", nullable(Type::Integer))
        .property("regenerate", nullable(Type::String))
        .property("sizes", ints())
        .property("limit_per_size", nullable(Type::Integer))
        .property("validation", string());
        let training = object(&[
            "epochs",
            "planned_epochs",
            "recipe",
            "minutes",
            "samples",
            "samples_per_second",
            "cpus",
            "best_epoch",
        ])
        .property("epochs", integer())
        .property("planned_epochs", integer())
        .property("recipe", free())
        .property("minutes", number())
        .property("samples", integer())
        .property("samples_per_second", number())
        .property("cpus", ArrayBuilder::new().items(string()))
        .property("best_epoch", nullable(Type::Integer));
        let domain = object(&["domain", "margin", "trained_sizes"])
            .property("domain", free())
            .property("margin", free())
            .property("trained_sizes", ints());
        card = card
            .property("name", string())
            .property("task", string_enum(&["forward", "policy"], None))
            .property("arch", string_enum(&["gnn", "pointnet"], None))
            .property("architecture", string())
            .property("feature_layout_version", integer())
            .property("normalisation", free())
            .property("training_data", training_data)
            .property("training_command", string())
            .property("training_commands", ArrayBuilder::new().items(string()))
            .property("training_config", free())
            .property("seed", integer())
            .property("git_commit", string())
            .property("training", training)
            .property("validation", AnyJson::schema())
            .property("units", string())
            .property("domain", domain)
            .property(
                "encoding",
                string_enum(
                    &treemanip_core::graph::path::Encoding::ALL.map(|e| e.name()),
                    Some("What graph the model reads and what it answers: `full` (the paper's: every node, at most 64; Δp per node), `path_rotation` (the push's path and side branches, any size; each path branch's turn) or `path` (the same graph; Δp per graph node: the first path model's)."),
                ),
            );
        card.into()
    }
}
impl ToSchema for ModelCard {}

/// Any JSON value.
pub struct AnyJson;

impl PartialSchema for AnyJson {
    fn schema() -> RefOr<Schema> {
        Schema::Object(
            ObjectBuilder::new()
                .schema_type(SchemaType::AnyValue)
                .build(),
        )
        .into()
    }
}

/// An angle (rad) within ±2π.
pub fn angle() -> Schema {
    ObjectBuilder::new()
        .schema_type(Type::Number)
        .minimum(Some(-std::f64::consts::TAU))
        .maximum(Some(std::f64::consts::TAU))
        .build()
        .into()
}

/// `robot.base_rpy`: three angles, or null.
pub fn base_rpy() -> Schema {
    ArrayBuilder::new()
        .schema_type(SchemaType::from_iter([Type::Array, Type::Null]))
        .items(RefOr::T(angle()))
        .min_items(Some(3))
        .max_items(Some(3))
        .description(Some(
            "The fixed base's orientation [roll, pitch, yaw] (rad, as URDF's rpy: R = Rz(yaw) Ry(pitch) Rx(roll)); default upright facing +x. A tilted or hanging mount (roll π). Only with `base` (a base region chooses its own heading).",
        ))
        .build()
        .into()
}

/// A string taking one of `values`.
pub fn string_enum(values: &[&str], description: Option<&str>) -> Schema {
    ObjectBuilder::new()
        .schema_type(Type::String)
        .enum_values(Some(values.iter().copied()))
        .description(description)
        .build()
        .into()
}

/// A string that is always `value` (an enum of one: utoipa has no
/// `const`).
pub fn constant(value: &str) -> Schema {
    string_enum(&[value], None)
}

/// A JSON object of string values (a map from a name to why).
pub fn string_map(description: &str) -> Schema {
    ObjectBuilder::new()
        .schema_type(Type::Object)
        .additional_properties(Some(AdditionalProperties::RefOr(
            ObjectBuilder::new().schema_type(Type::String).into(),
        )))
        .description(Some(description))
        .build()
        .into()
}
