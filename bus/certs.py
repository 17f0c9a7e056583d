"""A split deployment's credentials and Zenoh configs: a CA, mutual-TLS certificates, access control.

`make_deployment(out, ground="10.0.0.1")` writes, under `out`:

    ca.pem ca.key                       the deployment's certificate authority (keep ca.key offline)
    ground-router.pem/.key              the ground router's server certificate (SANs: the ground address,
                                        127.0.0.1, localhost, ground)
    ground.pem/.key                     the ground services' client certificate (common name `ground`)
    air-{uav}.pem/.key                  the air router's client certificate (common name `air-{uav}`)
    zenoh/split-ground-router.json5     the ground router: TLS only, mutual authentication, access control
    zenoh/split-ground.json5            ground services: clients of the ground router over TLS
    zenoh/split-air-router.json5        the air router: listens on the air host's loopback, dials the ground
                                        over TLS, never forwards camera images over the radio link
    zenoh/split-air.json5               air services: clients of the air router on loopback

The Zenoh configs are rendered from the templates in compose/zenoh/ (`${certs}`, `${ground}`, `${port}`,
`${air_port}` are filled in), plus the access-control blocks built here. Certificates come from the
`openssl` command line (OpenSSL 3): EC P-256 keys, X.509 v3 with subjectAltName and extendedKeyUsage,
which is what rustls (Zenoh's TLS) requires. See docs/deployment.md.
"""

from __future__ import annotations

import ipaddress
import json
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import json5

from atr.errors import ConfigError

REPO = Path(__file__).resolve().parents[1]
TEMPLATES = REPO / "compose" / "zenoh"
TEMPLATE_NAMES = ("split-ground-router", "split-ground", "split-air-router", "split-air")

GROUND_ROUTER = "ground-router"
GROUND = "ground"
DEFAULT_PORT = 7447  # Zenoh's registered port
DEFAULT_AIR_PORT = 7448  # the air router, on the air host's loopback only
DEFAULT_DAYS = 825  # certificate lifetime; the CA lives ten years

# Message kinds of Zenoh's access control (zenoh 1.x `access_control.rules[].messages`).
_ALL_MESSAGES = [
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "liveliness_query",
    "declare_liveliness_subscriber",
]
# What the air side computes (docs/deployment.md): its services' own keys.
AIR_SERVICES = ("sensor_source", "pose_integrator", "sfm")
# What lock-step's answer watch on the air subscribes to, for any vehicle (bus/answers.py).
ANSWER_WATCH = ("atr/*/detections", "atr/*/*/errors", "atr/*/*/status")


def air_name(uav: str) -> str:
    """Common name of a vehicle's air-router certificate."""
    return f"air-{uav}"


@dataclass(frozen=True)
class Deployment:
    """Where `make_deployment` wrote things."""

    root: Path
    uav: str
    ground: str
    port: int

    def cert(self, name: str) -> Path:
        """Certificate file of `name` (e.g. "ground", "air-uav1", "ca")."""
        return self.root / f"{name}.pem"

    def key(self, name: str) -> Path:
        """Private key file of `name`."""
        return self.root / f"{name}.key"

    def zenoh(self, name: str) -> Path:
        """Path of a Zenoh config file by name: "split-air" -> out/zenoh/split-air.json5."""
        return self.root / "zenoh" / f"{name}.json5"


def _openssl(*args: str, cwd: Path) -> None:
    if shutil.which("openssl") is None:
        raise ConfigError(
            "the openssl command was not found; install OpenSSL 3 (Debian: apt-get install openssl)"
        )
    result = subprocess.run(["openssl", *args], cwd=cwd, capture_output=True, text=True, timeout=60)
    if result.returncode != 0:
        raise ConfigError(f"openssl {args[0]} failed: {result.stderr.strip()}")


_HOST_LABEL = re.compile(r"^(?!-)[A-Za-z0-9-]{1,63}(?<!-)$")


def check_address(address: str, what: str) -> None:
    """Refuse an address that is neither an IP address nor a DNS host name (RFC 1123).

    Raises:
        ConfigError: naming the value and the expected form.

    """
    try:
        ipaddress.ip_address(address)
        return
    except ValueError:
        pass
    labels = address.removesuffix(".").split(".")
    if 0 < len(address) <= 253 and all(_HOST_LABEL.match(label) for label in labels):
        return
    hint = "; the port goes in --port" if address.count(":") == 1 else ""
    raise ConfigError(
        f"{what} {address!r} is neither an IP address (e.g. 10.0.0.1, fd00::1) nor a host name "
        f"(letters, digits and '-' in dot-separated labels, e.g. ground.example.org){hint}"
    )


def _subject_alt_names(hosts: list[str]) -> str:
    names = []
    for host in dict.fromkeys(hosts):  # keep order, drop duplicates
        try:
            ipaddress.ip_address(host)
            names.append(f"IP:{host}")
        except ValueError:
            names.append(f"DNS:{host}")
    return ",".join(names)


# `openssl req` options for a new unencrypted EC P-256 key, written to the file named next
_NEW_KEY = ("-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-keyout")


def make_ca(out: Path, name: str = "atr-deployment-ca", days: int = 3650) -> None:
    """Write out/ca.pem and out/ca.key (a self-signed EC P-256 certificate authority)."""
    out.mkdir(parents=True, exist_ok=True)
    _openssl(
        "req",
        "-x509",
        *_NEW_KEY,
        "ca.key",
        "-out",
        "ca.pem",
        "-days",
        str(days),
        "-subj",
        f"/CN={name}",
        "-addext",
        "basicConstraints=critical,CA:TRUE",
        "-addext",
        "keyUsage=critical,keyCertSign,cRLSign",
        cwd=out,
    )
    (out / "ca.key").chmod(0o600)


def issue(out: Path, name: str, *, hosts: list[str] = (), days: int = DEFAULT_DAYS) -> None:
    """Write out/{name}.pem and .key signed by out/ca.pem; `hosts` become subjectAltNames (server use).

    The certificate's common name is `name`: the access control matches peers on it.
    """
    if not (out / "ca.key").exists():
        raise ConfigError(f"no CA key in {out}; make the CA first (make_ca)")
    extensions = [
        "basicConstraints=critical,CA:FALSE",
        "keyUsage=critical,digitalSignature",
        "extendedKeyUsage=serverAuth,clientAuth",
    ]
    if hosts:
        extensions.append(f"subjectAltName={_subject_alt_names(list(hosts))}")
    (out / f"{name}.ext").write_text("\n".join(extensions) + "\n")
    _openssl(
        "req",
        "-new",
        *_NEW_KEY,
        f"{name}.key",
        "-out",
        f"{name}.csr",
        "-subj",
        f"/CN={name}",
        cwd=out,
    )
    _openssl(
        "x509",
        "-req",
        "-in",
        f"{name}.csr",
        "-CA",
        "ca.pem",
        "-CAkey",
        "ca.key",
        "-CAcreateserial",
        "-out",
        f"{name}.pem",
        "-days",
        str(days),
        "-extfile",
        f"{name}.ext",
        cwd=out,
    )
    (out / f"{name}.key").chmod(0o600)
    for leftover in (f"{name}.csr", f"{name}.ext"):
        (out / leftover).unlink()


def ground_access_control(uav: str, matcher_on_air: bool = False) -> dict[str, Any]:
    """The ground router's access control: deny by default; `ground` may do anything; `air-{uav}` may
    publish only its own services' keys and its truth, subscribe under `atr/{uav}/**` (and to what
    lock-step's answer watch asks for: the air still receives only `atr/{uav}/**`), and query templates.

    With the matcher on the air, the air may also publish `atr/{uav}/detections`, `atr/{uav}/guidance`
    and the matcher's keys.

    Recovery after an outage (bus/reliable.py: zenoh-ext's advanced publisher/subscriber): the air may
    declare the caches of its own keys (`KEY/@adv/pub/**`), send their heartbeats and reply from them;
    each side may query the other's caches (`**/@adv/**`); the air receives only replies and heartbeats
    of its own vehicle's keys. Key expressions name `@adv` explicitly: `**` does not match a chunk that
    starts with `@`.
    """
    services = list(AIR_SERVICES) + (["atr_matcher"] if matcher_on_air else [])
    air_puts = [
        f"atr/{uav}/camera/image",
        f"atr/{uav}/imu",
        f"atr/{uav}/lidar/cloud",
        f"atr/{uav}/pose/camera",
        f"atr/{uav}/pose/relative",
        f"atr/{uav}/sfm/cloud",
        f"sim/{uav}/truth",
    ]
    air_puts += [
        f"atr/{uav}/{service}/{kind}"
        for service in services
        for kind in ("status", "errors", "timing")
    ]
    if matcher_on_air:
        air_puts += [f"atr/{uav}/detections", f"atr/{uav}/guidance"]
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": [
            {
                "id": "ground-all",
                "permission": "allow",
                "flows": ["ingress", "egress"],
                "messages": _ALL_MESSAGES,
                # `**` does not match chunks that start with `@`: the caches' `KEY/@adv/...`
                "key_exprs": ["**", "**/@adv/**"],
            },
            {
                "id": "air-publish",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["put"],
                # its keys, and their publishers' heartbeats (the last sequence number)
                "key_exprs": sorted(set(air_puts) | {f"{key}/@adv/pub/**" for key in air_puts}),
            },
            {
                "id": "air-subscribe",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["declare_subscriber"],
                # and what lock-step's answer watch asks for, for any vehicle (bus/answers.py):
                # the air still receives only its own vehicle's keys (air-receive)
                "key_exprs": [
                    f"atr/{uav}/**",
                    f"sim/{uav}/**",
                    f"atr/{uav}/**/@adv/pub/**",
                    f"sim/{uav}/**/@adv/pub/**",
                    *[f"{key}{suffix}" for key in ANSWER_WATCH for suffix in ("", "/@adv/pub/**")],
                ],
            },
            {
                "id": "air-caches",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["declare_queryable"],
                "key_exprs": sorted({f"{key}/@adv/pub/**" for key in air_puts}),
            },
            {
                "id": "air-cache-replies",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["reply"],
                "key_exprs": sorted(set(air_puts) | {f"{key}/@adv/pub/**" for key in air_puts}),
            },
            {
                "id": "recovery-queries",
                "permission": "allow",
                "flows": ["ingress", "egress"],
                "messages": ["query"],
                "key_exprs": ["**/@adv/**"],
            },
            {
                "id": "air-receive-replies",
                "permission": "allow",
                "flows": ["egress"],
                "messages": ["reply"],
                "key_exprs": [f"atr/{uav}/**", f"atr/{uav}/**/@adv/pub/**"],
            },
            {
                "id": "air-query-templates",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["query"],
                "key_exprs": ["atr/templates/**"],
            },
            # What the ground sends to the air: its own vehicle's keys, template replies, and the ground's
            # interests (subscriptions, queryables), without which the air router would not forward anything.
            {
                "id": "air-receive",
                "permission": "allow",
                "flows": ["egress"],
                "messages": ["put"],
                "key_exprs": [f"atr/{uav}/**", f"atr/{uav}/**/@adv/pub/**"],
            },
            {
                "id": "air-receive-templates",
                "permission": "allow",
                "flows": ["egress"],
                "messages": ["reply"],
                "key_exprs": ["atr/templates/**"],
            },
            {
                "id": "air-learn-interests",
                "permission": "allow",
                "flows": ["egress"],
                "messages": ["declare_subscriber", "declare_queryable"],
                "key_exprs": ["**", "**/@adv/**"],
            },
        ],
        "subjects": [
            {"id": "ground", "cert_common_names": [GROUND]},
            {"id": "air", "cert_common_names": [air_name(uav)]},
        ],
        "policies": [
            {"id": "ground", "rules": ["ground-all"], "subjects": ["ground"]},
            {
                "id": "air",
                "subjects": ["air"],
                "rules": [
                    "air-publish",
                    "air-subscribe",
                    "air-caches",
                    "air-cache-replies",
                    "recovery-queries",
                    "air-receive-replies",
                    "air-query-templates",
                    "air-receive",
                    "air-receive-templates",
                    "air-learn-interests",
                ],
            },
        ],
    }


def air_access_control(images_to_ground: bool = False) -> dict[str, Any]:
    """The air router's access control: everything allowed, except camera images over the radio link.

    The radio link is the only TLS link of the air router (its air-side services dial it over TCP on loopback),
    so `link_protocols: ["tls"]` names exactly the air→ground link. Zenoh routes a publication only towards
    subscribers, but the ground recorder subscribes to everything; this rule is what keeps images on the air.
    """
    if images_to_ground:
        return {"enabled": False}
    return {
        "enabled": True,
        "default_permission": "allow",
        "rules": [
            {
                # nor their publisher's cache (its replies, its heartbeats, its very existence):
                # a ground subscriber's recovery would otherwise fetch the images from it
                "id": "images-stay-on-air",
                "permission": "deny",
                "flows": ["egress"],
                "messages": ["put", "reply", "declare_queryable"],
                "key_exprs": ["atr/*/camera/image", "atr/*/camera/image/@adv/**"],
            }
        ],
        "subjects": [{"id": "radio-link", "link_protocols": ["tls"]}],
        "policies": [{"id": "radio", "rules": ["images-stay-on-air"], "subjects": ["radio-link"]}],
    }


def render_config(name: str, values: dict[str, str]) -> dict[str, Any]:
    """A compose/zenoh template as a dict, with `${name}` tokens replaced by `values`.

    Raises:
        ConfigError: unknown template or a token without a value.

    """
    path = TEMPLATES / f"{name}.json5"
    if not path.exists():
        raise ConfigError(f"zenoh template {path} not found; expected one of {TEMPLATE_NAMES}")
    text = path.read_text()
    for token, value in values.items():
        text = text.replace("${" + token + "}", str(value))
    if "${" in text:
        start = text.index("${")
        raise ConfigError(
            f"template {path.name}: no value for {text[start : text.index('}', start) + 1]}"
        )
    return json5.loads(text)


def seal_key_name(uav: str) -> str:
    """File stem of the air recorder's Ed25519 signing key: `air-{uav}-recorder.key` / `.pub`."""
    return f"air-{uav}-recorder"


def seal_key(root: Path, uav: str) -> Path:
    """The air recorder's signing key pair in `root`, made once: a verifier has pinned the public
    key, so an existing pair is kept, never replaced. Returns the public key's path.
    """
    from bus.seal import generate_keys

    public = root / f"{seal_key_name(uav)}.pub"
    if not public.exists():
        generate_keys(root, seal_key_name(uav))
    return public


def make_deployment(
    out: str | Path,
    *,
    ground: str,
    uav: str = "uav1",
    port: int = DEFAULT_PORT,
    air_port: int = DEFAULT_AIR_PORT,
    matcher_on_air: bool = False,
    images_to_ground: bool = False,
    extra_hosts: list[str] = (),
    days: int = DEFAULT_DAYS,
) -> Deployment:
    """Write a deployment's CA, certificates and Zenoh configs under `out` (see the module docstring).

    Args:
        out: folder to write (created; existing certificates there are replaced).
        ground: the ground router's address as the air reaches it (IP or DNS name).
        uav: the vehicle id whose keys the air certificate may publish.
        port: the ground router's TLS port.
        air_port: the air router's loopback port.
        matcher_on_air: the air may publish detections (the layout runs the matcher on the air).
        images_to_ground: let camera images cross the radio link.
        extra_hosts: more names/addresses the ground router answers on (subjectAltNames).
        days: certificate lifetime, days.

    Raises:
        ConfigError: a bad argument or an openssl failure.

    """
    check_address(ground, "ground address")
    for host in extra_hosts:
        check_address(host, "--host")
    if not 0 < port < 65536 or not 0 < air_port < 65536:
        raise ConfigError(f"ports {port}, {air_port} must be in 1..65535")
    root = Path(out).resolve()
    make_ca(root)
    issue(
        root,
        GROUND_ROUTER,
        hosts=[ground, "127.0.0.1", "localhost", "ground", *extra_hosts],
        days=days,
    )
    issue(root, GROUND, days=days)
    issue(root, air_name(uav), days=days)
    seal_key(root, uav)
    host = f"[{ground}]" if ":" in ground else ground  # an IPv6 address in an endpoint
    values = {
        "certs": str(root),
        "ground": host,
        "port": str(port),
        "air_port": str(air_port),
        "uav": uav,
    }
    (root / "zenoh").mkdir(exist_ok=True)
    for name in TEMPLATE_NAMES:
        config = render_config(name, values | {"air_cert": air_name(uav)})
        if name == "split-ground-router":
            config["access_control"] = ground_access_control(uav, matcher_on_air)
        elif name == "split-air-router":
            config["access_control"] = air_access_control(images_to_ground)
        header = f"// Rendered by `atr certs` from compose/zenoh/{name}.json5 for {uav}; see docs/deployment.md.\n"
        (root / "zenoh" / f"{name}.json5").write_text(header + json.dumps(config, indent=2) + "\n")
    return Deployment(root, uav, ground, port)
