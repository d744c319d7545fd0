//! rmw_zenoh's names and metadata, as its Jazzy and Kilted releases (0.2.x, 0.6.x) write
//! them, so that ROS 2 nodes on `rmw_zenoh_cpp` see the bridge's topics as their own:
//!
//! - data key expression `<domain>/<topic without leading slash>/<DDS type>/<RIHS01 hash>`;
//! - liveliness tokens `@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<NN|MP>/<enclave>/
//!   <namespace>/<node>[/<topic>/<DDS type>/<hash>/<QoS>]`, each `/` inside a part
//!   replaced by `%`;
//! - the QoS part, fields equal to rmw_zenoh's defaults left empty;
//! - the attachment of every sample: sequence number, source timestamp and the
//!   publisher's GID, in zenoh-ext's serialisation.

use super::msgs::RosType;

/// The admin space of rmw_zenoh's liveliness tokens.
pub const ADMIN_SPACE: &str = "@ros2_lv";

/// A ROS 2 node as rmw_zenoh announces it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Node {
    /// `ROS_DOMAIN_ID`.
    pub domain: u32,
    /// The Zenoh session id, as Zenoh prints it.
    pub zid: String,
    /// The node's entity id within its session.
    pub id: usize,
    /// The security enclave, `/` without one.
    pub enclave: String,
    /// The node namespace, `/` for none.
    pub namespace: String,
    /// The node name.
    pub name: String,
}

/// Replaces each `/` by `%`, as rmw_zenoh does inside a token's parts.
pub fn mangle(part: &str) -> String {
    part.replace('/', "%")
}

/// The key expression of `topic`'s samples of type `ty` in `domain`.
pub fn topic_key(domain: u32, topic: &str, ty: &RosType) -> String {
    let topic = topic.strip_prefix('/').unwrap_or(topic);
    let topic = topic.strip_suffix('/').unwrap_or(topic);
    format!("{domain}/{topic}/{}/{}", ty.dds_name, ty.hash)
}

impl Node {
    /// The liveliness token of an entity of this node: `kind` `NN` (the node itself) or
    /// `MP` (a publisher).
    fn token(&self, entity: usize, kind: &str) -> String {
        format!(
            "{ADMIN_SPACE}/{}/{}/{}/{entity}/{kind}/{}/{}/{}",
            self.domain,
            self.zid,
            self.id,
            mangle(&self.enclave),
            mangle(&self.namespace),
            mangle(&self.name)
        )
    }

    /// The node's own liveliness token.
    pub fn node_token(&self) -> String {
        self.token(self.id, "NN")
    }

    /// The liveliness token of the publisher `entity` on `topic`.
    pub fn publisher_token(&self, entity: usize, topic: &str, ty: &RosType, qos: &Qos) -> String {
        format!(
            "{}/{}/{}/{}/{}",
            self.token(entity, "MP"),
            mangle(topic),
            mangle(ty.dds_name),
            mangle(ty.hash),
            qos.key()
        )
    }
}

/// The QoS policies the bridge's publishers use; the rest (deadline, lifespan,
/// liveliness and its lease) are rmw_zenoh's defaults.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// Reliable (else best effort).
    pub reliable: bool,
    /// Transient local (else volatile).
    pub transient_local: bool,
    /// Keep-last depth.
    pub depth: usize,
}

/// rmw_zenoh's default depth: a depth equal to it is written as an empty field.
const DEFAULT_DEPTH: usize = 42;

impl Qos {
    /// rclcpp's default publisher QoS: reliable, volatile, keep last 10.
    pub const DEFAULT: Qos = Qos {
        reliable: true,
        transient_local: false,
        depth: 10,
    };

    /// The token part `reliability:durability:history,depth:deadline s,ns:lifespan
    /// s,ns:liveliness,lease s,lease ns`, each value empty when it is rmw_zenoh's
    /// default (reliable, volatile, keep last 42, the rest infinite or automatic). The
    /// codes are rmw's enums: best effort 2, transient local 1.
    pub fn key(&self) -> String {
        let reliability = if self.reliable { "" } else { "2" };
        let durability = if self.transient_local { "1" } else { "" };
        let depth = if self.depth == DEFAULT_DEPTH {
            String::new()
        } else {
            self.depth.to_string()
        };
        format!("{reliability}:{durability}:,{depth}:,:,:,,")
    }
}

/// The GID rmw_zenoh derives from an entity's liveliness token: XXH3-128 of the token,
/// its low 64 bits then its high 64 bits, each little-endian.
pub fn gid(token: &str) -> [u8; 16] {
    xxhash_rust::xxh3::xxh3_128(token.as_bytes()).to_le_bytes()
}

/// The attachment of a sample: `i64` sequence number (from 1 per publisher), `i64`
/// source timestamp (CLOCK_REALTIME, ns), the 16-byte GID, in zenoh-ext's serialisation
/// (little-endian integers; the array prefixed by its length as a LEB128 varint).
pub fn attachment(sequence: i64, source_timestamp_ns: i64, gid: &[u8; 16]) -> Vec<u8> {
    zenoh_ext::z_serialize(&(sequence, source_timestamp_ns, *gid))
        .to_bytes()
        .into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bridge::msgs::POSE_STAMPED;

    fn node() -> Node {
        Node {
            domain: 0,
            zid: "8f2e1f8c2d0a4b6e9c1d3f5a7b9c0d1e".into(),
            id: 0,
            enclave: "/".into(),
            namespace: "/".into(),
            name: "photopose_bridge".into(),
        }
    }

    #[test]
    fn topic_keys_drop_the_leading_slash() {
        assert_eq!(
            topic_key(0, "/photopose/cup/pose", &POSE_STAMPED),
            "0/photopose/cup/pose/geometry_msgs::msg::dds_::PoseStamped_/\
             RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8"
        );
    }

    #[test]
    fn tokens_have_the_rmw_zenoh_parts() {
        let n = node();
        assert_eq!(
            n.node_token(),
            "@ros2_lv/0/8f2e1f8c2d0a4b6e9c1d3f5a7b9c0d1e/0/0/NN/%/%/photopose_bridge"
        );
        let token = n.publisher_token(3, "/photopose/cup/pose", &POSE_STAMPED, &Qos::DEFAULT);
        let parts: Vec<&str> = token.split('/').collect();
        assert_eq!(parts.len(), 13, "{token}");
        assert_eq!(
            parts[..9],
            ["@ros2_lv", "0", &n.zid, "0", "3", "MP", "%", "%", "photopose_bridge"]
        );
        assert_eq!(parts[9], "%photopose%cup%pose");
        assert_eq!(parts[10], POSE_STAMPED.dds_name);
        assert_eq!(parts[11], POSE_STAMPED.hash);
        assert_eq!(parts[12], "::,10:,:,:,,");
    }

    #[test]
    fn qos_fields_equal_to_the_defaults_are_empty() {
        let q = |reliable, transient_local, depth| {
            Qos {
                reliable,
                transient_local,
                depth,
            }
            .key()
        };
        assert_eq!(q(true, false, 42), "::,:,:,:,,");
        assert_eq!(q(false, true, 5), "2:1:,5:,:,:,,");
    }

    #[test]
    fn the_attachment_is_33_bytes() {
        let gid: [u8; 16] = core::array::from_fn(|i| i as u8);
        let a = attachment(1, 0x0102_0304_0506_0708, &gid);
        assert_eq!(a.len(), 33);
        assert_eq!(a[..8], 1i64.to_le_bytes());
        assert_eq!(a[8..16], 0x0102_0304_0506_0708i64.to_le_bytes());
        assert_eq!(a[16], 16);
        assert_eq!(a[17..], gid);
    }

    #[test]
    fn gids_are_xxh3_128_of_the_token() {
        // XXH3-128 of the empty input, seed 0 (xxHash's reference value
        // 99aa06d3014798d86001c324468d497f: high then low 64 bits).
        let g = gid("");
        assert_eq!(g[..8], 0x6001_c324_468d_497fu64.to_le_bytes());
        assert_eq!(g[8..], 0x99aa_06d3_0147_98d8u64.to_le_bytes());
    }
}
