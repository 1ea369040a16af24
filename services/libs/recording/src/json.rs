//! The JSON of a recording: serde JSON, except that non-finite floats are the strings
//! `"NaN"`, `"inf"` and `"-inf"`.
//!
//! serde_json writes NaN and the infinities as `null`, which no `f64` field reads back: a
//! recorded request with a NaN (a faulty sensor, a hostile peer) could not be replayed. The
//! mapping is done here, around the messages' own serde derives, so that the wire format
//! (docs/protocol.md) is untouched: [`to_vec`] wraps the serializer, [`from_slice`] reads
//! through a deserializer that turns those three strings into floats where a float is
//! expected (and leaves them strings everywhere else).

use serde::de::value::StringDeserializer;
use serde::de::{self, DeserializeOwned, DeserializeSeed, IntoDeserializer, Visitor};
use serde::ser::{self, Serialize, Serializer};
use serde_json::{Map, Value};

/// The string a non-finite float is written as.
fn non_finite_name(v: f64) -> &'static str {
    if v.is_nan() {
        "NaN"
    } else if v > 0.0 {
        "inf"
    } else {
        "-inf"
    }
}

/// The float a string stands for, if it is one of the three names.
fn non_finite_value(s: &str) -> Option<f64> {
    match s {
        "NaN" => Some(f64::NAN),
        "inf" => Some(f64::INFINITY),
        "-inf" => Some(f64::NEG_INFINITY),
        _ => None,
    }
}

/// `value` as recording JSON.
pub fn to_vec<T: Serialize + ?Sized>(value: &T) -> serde_json::Result<Vec<u8>> {
    serde_json::to_vec(&NonFinite(value))
}

/// Reads recording JSON (plain serde JSON too: it is a superset).
pub fn from_slice<T: DeserializeOwned>(data: &[u8]) -> serde_json::Result<T> {
    let value: Value = serde_json::from_slice(data)?;
    T::deserialize(Lenient(value))
}

/// Serializes the wrapped value with non-finite floats as strings.
struct NonFinite<'a, T: ?Sized>(&'a T);

impl<T: Serialize + ?Sized> Serialize for NonFinite<'_, T> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(Wrap(serializer))
    }
}

/// A serializer (or one of its compound serializers) whose nested values go through
/// [`NonFinite`].
struct Wrap<S>(S);

macro_rules! forward {
    ($($method:ident($($arg:ident: $ty:ty),*);)*) => {
        $(fn $method(self, $($arg: $ty),*) -> Result<S::Ok, S::Error> {
            self.0.$method($($arg),*)
        })*
    };
}

impl<S: Serializer> Serializer for Wrap<S> {
    type Ok = S::Ok;
    type Error = S::Error;
    type SerializeSeq = Wrap<S::SerializeSeq>;
    type SerializeTuple = Wrap<S::SerializeTuple>;
    type SerializeTupleStruct = Wrap<S::SerializeTupleStruct>;
    type SerializeTupleVariant = Wrap<S::SerializeTupleVariant>;
    type SerializeMap = Wrap<S::SerializeMap>;
    type SerializeStruct = Wrap<S::SerializeStruct>;
    type SerializeStructVariant = Wrap<S::SerializeStructVariant>;

    forward! {
        serialize_bool(v: bool);
        serialize_i8(v: i8);
        serialize_i16(v: i16);
        serialize_i32(v: i32);
        serialize_i64(v: i64);
        serialize_i128(v: i128);
        serialize_u8(v: u8);
        serialize_u16(v: u16);
        serialize_u32(v: u32);
        serialize_u64(v: u64);
        serialize_u128(v: u128);
        serialize_char(v: char);
        serialize_str(v: &str);
        serialize_bytes(v: &[u8]);
        serialize_none();
        serialize_unit();
        serialize_unit_struct(name: &'static str);
        serialize_unit_variant(name: &'static str, index: u32, variant: &'static str);
    }

    fn serialize_f32(self, v: f32) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            self.0.serialize_f32(v)
        } else {
            self.0.serialize_str(non_finite_name(f64::from(v)))
        }
    }

    fn serialize_f64(self, v: f64) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            self.0.serialize_f64(v)
        } else {
            self.0.serialize_str(non_finite_name(v))
        }
    }

    fn serialize_some<T: Serialize + ?Sized>(self, value: &T) -> Result<S::Ok, S::Error> {
        self.0.serialize_some(&NonFinite(value))
    }

    fn serialize_newtype_struct<T: Serialize + ?Sized>(self, name: &'static str, value: &T) -> Result<S::Ok, S::Error> {
        self.0.serialize_newtype_struct(name, &NonFinite(value))
    }

    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        name: &'static str,
        index: u32,
        variant: &'static str,
        value: &T,
    ) -> Result<S::Ok, S::Error> {
        self.0
            .serialize_newtype_variant(name, index, variant, &NonFinite(value))
    }

    fn serialize_seq(self, len: Option<usize>) -> Result<Self::SerializeSeq, S::Error> {
        self.0.serialize_seq(len).map(Wrap)
    }

    fn serialize_tuple(self, len: usize) -> Result<Self::SerializeTuple, S::Error> {
        self.0.serialize_tuple(len).map(Wrap)
    }

    fn serialize_tuple_struct(self, name: &'static str, len: usize) -> Result<Self::SerializeTupleStruct, S::Error> {
        self.0.serialize_tuple_struct(name, len).map(Wrap)
    }

    fn serialize_tuple_variant(
        self,
        name: &'static str,
        index: u32,
        variant: &'static str,
        len: usize,
    ) -> Result<Self::SerializeTupleVariant, S::Error> {
        self.0.serialize_tuple_variant(name, index, variant, len).map(Wrap)
    }

    fn serialize_map(self, len: Option<usize>) -> Result<Self::SerializeMap, S::Error> {
        self.0.serialize_map(len).map(Wrap)
    }

    fn serialize_struct(self, name: &'static str, len: usize) -> Result<Self::SerializeStruct, S::Error> {
        self.0.serialize_struct(name, len).map(Wrap)
    }

    fn serialize_struct_variant(
        self,
        name: &'static str,
        index: u32,
        variant: &'static str,
        len: usize,
    ) -> Result<Self::SerializeStructVariant, S::Error> {
        self.0.serialize_struct_variant(name, index, variant, len).map(Wrap)
    }

    fn is_human_readable(&self) -> bool {
        self.0.is_human_readable()
    }
}

/// The compound serializers with one "add an element" method.
macro_rules! compound {
    ($($trait:ident, $method:ident;)*) => {
        $(impl<S: ser::$trait> ser::$trait for Wrap<S> {
            type Ok = S::Ok;
            type Error = S::Error;

            fn $method<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), S::Error> {
                self.0.$method(&NonFinite(value))
            }

            fn end(self) -> Result<S::Ok, S::Error> {
                self.0.end()
            }
        })*
    };
}

compound! {
    SerializeSeq, serialize_element;
    SerializeTuple, serialize_element;
    SerializeTupleStruct, serialize_field;
    SerializeTupleVariant, serialize_field;
}

impl<S: ser::SerializeMap> ser::SerializeMap for Wrap<S> {
    type Ok = S::Ok;
    type Error = S::Error;

    fn serialize_key<T: Serialize + ?Sized>(&mut self, key: &T) -> Result<(), S::Error> {
        self.0.serialize_key(&NonFinite(key))
    }

    fn serialize_value<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), S::Error> {
        self.0.serialize_value(&NonFinite(value))
    }

    fn end(self) -> Result<S::Ok, S::Error> {
        self.0.end()
    }
}

/// The struct serializers, with named fields.
macro_rules! fields {
    ($($trait:ident;)*) => {
        $(impl<S: ser::$trait> ser::$trait for Wrap<S> {
            type Ok = S::Ok;
            type Error = S::Error;

            fn serialize_field<T: Serialize + ?Sized>(&mut self, key: &'static str, value: &T) -> Result<(), S::Error> {
                self.0.serialize_field(key, &NonFinite(value))
            }

            fn skip_field(&mut self, key: &'static str) -> Result<(), S::Error> {
                self.0.skip_field(key)
            }

            fn end(self) -> Result<S::Ok, S::Error> {
                self.0.end()
            }
        })*
    };
}

fields! {
    SerializeStruct;
    SerializeStructVariant;
}

/// A JSON value read as serde_json reads it, except that a float may be one of the three
/// strings; nested values are read the same way.
struct Lenient(Value);

impl<'de> de::Deserializer<'de> for Lenient {
    type Error = serde_json::Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> serde_json::Result<V::Value> {
        match self.0 {
            Value::Array(items) => {
                let len = items.len();
                let mut seq = Seq(items.into_iter());
                let value = visitor.visit_seq(&mut seq)?;
                match seq.0.len() {
                    0 => Ok(value),
                    left => Err(de::Error::invalid_length(len - left, &"fewer elements in the array")),
                }
            }
            Value::Object(map) => visitor.visit_map(Entries {
                entries: map.into_iter(),
                value: None,
            }),
            other => other.deserialize_any(visitor),
        }
    }

    fn deserialize_f64<V: Visitor<'de>>(self, visitor: V) -> serde_json::Result<V::Value> {
        match &self.0 {
            Value::String(s) => match non_finite_value(s) {
                Some(v) => visitor.visit_f64(v),
                None => self.0.deserialize_f64(visitor),
            },
            _ => self.0.deserialize_f64(visitor),
        }
    }

    fn deserialize_f32<V: Visitor<'de>>(self, visitor: V) -> serde_json::Result<V::Value> {
        match &self.0 {
            Value::String(s) => match non_finite_value(s) {
                Some(v) => visitor.visit_f32(v as f32),
                None => self.0.deserialize_f32(visitor),
            },
            _ => self.0.deserialize_f32(visitor),
        }
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> serde_json::Result<V::Value> {
        match self.0 {
            Value::Null => visitor.visit_none(),
            other => visitor.visit_some(Lenient(other)),
        }
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> serde_json::Result<V::Value> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        name: &'static str,
        variants: &'static [&'static str],
        visitor: V,
    ) -> serde_json::Result<V::Value> {
        match self.0 {
            Value::Object(map) if map.len() == 1 => {
                let (variant, value) = map.into_iter().next().expect("one entry");
                visitor.visit_enum(Variant {
                    variant,
                    value: Some(value),
                })
            }
            Value::String(variant) => visitor.visit_enum(Variant { variant, value: None }),
            other => other.deserialize_enum(name, variants, visitor),
        }
    }

    fn is_human_readable(&self) -> bool {
        true
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 char str string bytes byte_buf unit
        unit_struct seq tuple tuple_struct map struct identifier ignored_any
    }
}

/// The elements of an array.
struct Seq(std::vec::IntoIter<Value>);

impl<'de> de::SeqAccess<'de> for Seq {
    type Error = serde_json::Error;

    fn next_element_seed<T: DeserializeSeed<'de>>(&mut self, seed: T) -> serde_json::Result<Option<T::Value>> {
        self.0.next().map(|v| seed.deserialize(Lenient(v))).transpose()
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.0.len())
    }
}

/// The entries of an object.
struct Entries {
    entries: <Map<String, Value> as IntoIterator>::IntoIter,
    value: Option<Value>,
}

impl<'de> de::MapAccess<'de> for Entries {
    type Error = serde_json::Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(&mut self, seed: K) -> serde_json::Result<Option<K::Value>> {
        match self.entries.next() {
            Some((key, value)) => {
                self.value = Some(value);
                let key: StringDeserializer<serde_json::Error> = key.into_deserializer();
                seed.deserialize(key).map(Some)
            }
            None => Ok(None),
        }
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> serde_json::Result<V::Value> {
        match self.value.take() {
            Some(v) => seed.deserialize(Lenient(v)),
            None => Err(de::Error::custom("a value without its key")),
        }
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.entries.len())
    }
}

/// An enum: its variant's name and, unless it is a unit variant, its content.
struct Variant {
    variant: String,
    value: Option<Value>,
}

impl<'de> de::EnumAccess<'de> for Variant {
    type Error = serde_json::Error;
    type Variant = Self;

    fn variant_seed<V: DeserializeSeed<'de>>(mut self, seed: V) -> serde_json::Result<(V::Value, Self)> {
        let name: StringDeserializer<serde_json::Error> = std::mem::take(&mut self.variant).into_deserializer();
        Ok((seed.deserialize(name)?, self))
    }
}

impl<'de> de::VariantAccess<'de> for Variant {
    type Error = serde_json::Error;

    fn unit_variant(self) -> serde_json::Result<()> {
        match self.value {
            None | Some(Value::Null) => Ok(()),
            Some(_) => Err(de::Error::invalid_type(de::Unexpected::Map, &"a unit variant")),
        }
    }

    fn newtype_variant_seed<T: DeserializeSeed<'de>>(self, seed: T) -> serde_json::Result<T::Value> {
        match self.value {
            Some(v) => seed.deserialize(Lenient(v)),
            None => Err(de::Error::invalid_type(
                de::Unexpected::UnitVariant,
                &"a newtype variant",
            )),
        }
    }

    fn tuple_variant<V: Visitor<'de>>(self, _len: usize, visitor: V) -> serde_json::Result<V::Value> {
        match self.value {
            Some(v @ Value::Array(_)) => de::Deserializer::deserialize_any(Lenient(v), visitor),
            _ => Err(de::Error::invalid_type(de::Unexpected::UnitVariant, &"a tuple variant")),
        }
    }

    fn struct_variant<V: Visitor<'de>>(
        self,
        _fields: &'static [&'static str],
        visitor: V,
    ) -> serde_json::Result<V::Value> {
        match self.value {
            Some(v @ Value::Object(_)) => de::Deserializer::deserialize_any(Lenient(v), visitor),
            _ => Err(de::Error::invalid_type(
                de::Unexpected::UnitVariant,
                &"a struct variant",
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;

    #[derive(Debug, serde::Serialize, serde::Deserialize)]
    enum Shape {
        Unit,
        Point(f64),
        Pair(f64, f32),
        Named { r: f64 },
    }

    #[derive(Debug, serde::Serialize, serde::Deserialize)]
    struct Doc {
        a: f64,
        b: Vec<f64>,
        c: Option<f64>,
        d: Option<f64>,
        name: String,
        shapes: Vec<Shape>,
        map: BTreeMap<String, f32>,
        nested: (u8, f64),
    }

    fn same(a: f64, b: f64) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    #[test]
    fn non_finite_floats_are_named_strings_and_read_back() {
        let doc = Doc {
            a: f64::NAN,
            b: vec![1.5, f64::INFINITY, f64::NEG_INFINITY, -0.0],
            c: Some(f64::NAN),
            d: None,
            name: "inf".into(),
            shapes: vec![
                Shape::Unit,
                Shape::Point(f64::INFINITY),
                Shape::Pair(f64::NAN, f32::NEG_INFINITY),
                Shape::Named { r: f64::NEG_INFINITY },
            ],
            map: BTreeMap::from([("x".to_owned(), f32::NAN)]),
            nested: (3, f64::NAN),
        };
        let bytes = to_vec(&doc).expect("encoded");
        let text = String::from_utf8(bytes.clone()).expect("utf-8");
        // The only `null` is the `None`.
        assert_eq!(text.matches("null").count(), 1, "{text}");
        assert!(text.contains(r#""a":"NaN""#), "{text}");
        assert!(text.contains(r#""b":[1.5,"inf","-inf",-0.0]"#), "{text}");
        let back: Doc = from_slice(&bytes).expect("decoded");
        assert!(back.a.is_nan());
        assert_eq!(back.b.len(), 4);
        for (x, y) in back.b.iter().zip(&doc.b) {
            assert!(same(*x, *y), "{x} {y}");
        }
        assert!(back.c.is_some_and(f64::is_nan));
        assert_eq!(back.d, None);
        // A string field keeps the string.
        assert_eq!(back.name, "inf");
        assert!(matches!(back.shapes[0], Shape::Unit));
        assert!(matches!(back.shapes[1], Shape::Point(v) if v == f64::INFINITY));
        assert!(matches!(back.shapes[2], Shape::Pair(a, b) if a.is_nan() && b == f32::NEG_INFINITY));
        assert!(matches!(back.shapes[3], Shape::Named { r } if r == f64::NEG_INFINITY));
        assert!(back.map["x"].is_nan());
        assert_eq!(back.nested.0, 3);
        assert!(back.nested.1.is_nan());
    }

    #[test]
    fn plain_json_reads_as_with_serde_json() {
        let text = br#"{"a":1,"b":[2.5],"c":null,"d":3,"name":"x","shapes":["Unit",{"Point":1}],
            "map":{},"nested":[1,2]}"#;
        let doc: Doc = from_slice(text).expect("decoded");
        assert_eq!(doc.a, 1.0);
        assert_eq!(doc.c, None);
        assert_eq!(doc.d, Some(3.0));
        // Other strings are still type errors for a float, and wrong shapes are errors.
        assert!(from_slice::<Doc>(br#"{"a":"nan"}"#).is_err());
        assert!(from_slice::<(u8, u8)>(b"[1,2,3]").is_err());
        assert!(from_slice::<u8>(b"300").is_err());
    }
}
