#!/usr/bin/env bash
# Lab PKI for lodestone's DDS Security (Fast DDS 2.9 builtin plugins: PKI-DH, Access-Permissions,
# AES-GCM-GMAC). Creates a CA, one identity per name, a governance document and one permissions
# document per identity, all signed by the CA. See README.md next to this script.
#
#   make-lab-certs.sh OUTDIR [IDENTITY[=ROLE]...]
#
# IDENTITY defaults to: stage console observer. ROLE is one of stage|console|observer and
# defaults to the identity's own name (so `stage` has the stage role; `bench2=console` is a
# second console). Idempotent: existing keys and certificates are kept (a new identity can be
# added later under the same CA); documents are rewritten and re-signed only when their
# content changed or their signature no longer verifies. Never prompts.
set -euo pipefail

readonly VALIDITY_DAYS=3650          # 10 years: a lab CA must not expire in the middle of a campaign
readonly CURVE=prime256v1            # Fast DDS 2.9 PKI-DH: ECDSA-SHA256 on P-256 (or RSA-2048)
readonly ORGANIZATION=lodestone      # subject = O=lodestone, CN=<identity>
readonly DOMAIN_MIN=0
readonly DOMAIN_MAX=232

usage() {
  echo "usage: $0 OUTDIR [IDENTITY[=stage|console|observer]...]" >&2
  exit 2
}
[[ $# -ge 1 ]] || usage
[[ $1 != -* ]] || usage
command -v openssl >/dev/null || { echo "$0: openssl not found (apt-get install openssl)" >&2; exit 1; }

out=$1
shift
identities=("$@")
[[ ${#identities[@]} -gt 0 ]] || identities=(stage console observer)

# Check every argument before creating anything.
for spec in "${identities[@]}"; do
  name=${spec%%=*}
  role=${spec#*=}
  if [[ ! $name =~ ^[A-Za-z0-9_.-]+$ ]]; then
    echo "$0: identity '$name': use letters, digits, '.', '_' or '-'" >&2
    exit 2
  fi
  case $role in
    stage|console|observer) ;;
    *) echo "$0: identity '$spec': role '$role' is not stage, console or observer (write $name=ROLE)" >&2
       exit 2 ;;
  esac
done

mkdir -p "$out"
out=$(cd "$out" && pwd)
umask 077  # private keys are created 0600; public files are chmod 0644 below
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

say() { printf '%-6s %s\n' "$1" "$2"; }

# --- CA (identity CA and permissions CA are the same certificate in the lab) -----------------
ca_key=$out/ca.key.pem
ca_cert=$out/ca.cert.pem
if [[ -s $ca_key && -s $ca_cert ]]; then
  say kept "$ca_cert"
else
  openssl ecparam -name "$CURVE" -genkey -noout -out "$ca_key"
  openssl req -new -x509 -sha256 -key "$ca_key" -out "$ca_cert" -days "$VALIDITY_DAYS" \
    -subj "/O=$ORGANIZATION/CN=lodestone lab CA" \
    -addext "basicConstraints=critical,CA:TRUE" \
    -addext "keyUsage=critical,keyCertSign,cRLSign,digitalSignature"
  chmod 0644 "$ca_cert"
  say made "$ca_cert (and ca.key.pem: keep it off the lab machines)"
fi

# sign_document XML P7S: S/MIME, clear text (-text) as the DDS Security spec and Fast DDS expect.
sign_document() {
  openssl smime -sign -text -in "$1" -out "$2" -signer "$ca_cert" -inkey "$ca_key"
  chmod 0644 "$2"
}

# install_document TMP XML P7S: keep the existing files if the content and signature are current.
install_document() {
  local tmp=$1 xml=$2 p7s=$3
  if [[ -s $xml && -s $p7s ]] && cmp -s "$tmp" "$xml" &&
     openssl smime -verify -text -in "$p7s" -CAfile "$ca_cert" -out /dev/null 2>/dev/null; then
    say kept "$p7s"
    return
  fi
  cp "$tmp" "$xml"
  chmod 0644 "$xml"
  sign_document "$xml" "$p7s"
  say made "$p7s"
}

# document_head SCHEMA: the opening of a DDS Security document (SCHEMA: governance or
# permissions), up to its <dds> element.
document_head() {
  cat <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_$1.xsd">
EOF
}

# --- governance --------------------------------------------------------------------------------
# Commands and replies: only permitted identities may read/write them, and their metadata
# (submessages) are encrypted, so nobody on the wire can read or replay a command.
# Everything else (signals, state, timing, events, lode/signals): any authenticated participant
# may read and write; the payload is not encrypted per sample because telemetry is neither
# secret nor low-rate (several kHz per signal on two shared cores). It is still signed: with
# rtps_protection_kind SIGN every RTPS message carries a GMAC from the sender's session key, so
# telemetry cannot be forged or altered by a host that was not authenticated, at the cost of one
# GMAC per message instead of one AES-GCM per sample and submessage.
#
# protected_topic_rule EXPRESSION: the rule of a command-channel topic (commands and replies
# are protected alike).
protected_topic_rule() {
  cat <<EOF
        <topic_rule>
          <topic_expression>$1</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
EOF
}
{
  document_head governance
  cat <<EOF
  <domain_access_rules>
    <domain_rule>
      <domains>
        <id_range><min>$DOMAIN_MIN</min><max>$DOMAIN_MAX</max></id_range>
      </domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>SIGN</rtps_protection_kind>
      <topic_access_rules>
$(protected_topic_rule 'lode/*/command')
$(protected_topic_rule 'lode/*/reply')
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>false</enable_liveliness_protection>
          <enable_read_access_control>false</enable_read_access_control>
          <enable_write_access_control>false</enable_write_access_control>
          <metadata_protection_kind>NONE</metadata_protection_kind>
          <data_protection_kind>NONE</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
EOF
} >"$work/governance.xml"
install_document "$work/governance.xml" "$out/governance.xml" "$out/governance.p7s"

# --- identities ----------------------------------------------------------------------------------
# rules_for ROLE: the <allow_rule>/<deny_rule> elements of a grant. Rules are evaluated in order
# and the first match decides; the grant's <default> is DENY.
rules_for() {
  local domains="<domains><id_range><min>$DOMAIN_MIN</min><max>$DOMAIN_MAX</max></id_range></domains>"
  case $1 in
    stage) cat <<EOF
      <allow_rule>
        $domains
        <publish><topics><topic>lode/*</topic></topics></publish>
        <subscribe><topics><topic>lode/*/command</topic></topics></subscribe>
      </allow_rule>
EOF
      ;;
    console) cat <<EOF
      <allow_rule>
        $domains
        <publish><topics><topic>lode/*/command</topic></topics></publish>
        <subscribe><topics><topic>*</topic></topics></subscribe>
      </allow_rule>
EOF
      ;;
    observer) cat <<EOF
      <deny_rule>
        $domains
        <publish><topics><topic>lode/*/command</topic></topics></publish>
      </deny_rule>
      <allow_rule>
        $domains
        <subscribe><topics><topic>*</topic></topics></subscribe>
      </allow_rule>
EOF
      ;;
  esac
}

# DDS Security wants the validity as UTC "YYYY-MM-DDThh:mm:ss"; the grant's validity is the
# certificate's, so the document is the same every run (and only re-signed when it changes).
cert_date() {  # cert_date CERT startdate|enddate
  date -u -d "$(openssl x509 -in "$1" -noout "-$2" | cut -d= -f2)" +%Y-%m-%dT%H:%M:%S
}

for spec in "${identities[@]}"; do
  name=${spec%%=*}
  role=${spec#*=}
  key=$out/$name.key.pem
  cert=$out/$name.cert.pem
  if [[ -s $key && -s $cert ]] && openssl verify -CAfile "$ca_cert" "$cert" >/dev/null 2>&1; then
    say kept "$cert"
  else
    openssl ecparam -name "$CURVE" -genkey -noout -out "$key"
    openssl req -new -sha256 -key "$key" -out "$work/$name.csr" -subj "/O=$ORGANIZATION/CN=$name"
    printf '%s\n' "basicConstraints=critical,CA:FALSE" "keyUsage=critical,digitalSignature,keyAgreement" \
      >"$work/$name.ext"
    openssl x509 -req -sha256 -in "$work/$name.csr" -CA "$ca_cert" -CAkey "$ca_key" \
      -set_serial "0x$(openssl rand -hex 16)" -days "$VALIDITY_DAYS" \
      -extfile "$work/$name.ext" -out "$cert" 2>/dev/null
    chmod 0644 "$cert"
    say made "$cert ($name.key.pem)"
  fi

  {
    document_head permissions
    cat <<EOF
  <permissions>
    <grant name="${name}_grant">
      <subject_name>CN=$name,O=$ORGANIZATION</subject_name>
      <validity>
        <not_before>$(cert_date "$cert" startdate)</not_before>
        <not_after>$(cert_date "$cert" enddate)</not_after>
      </validity>
$(rules_for "$role")
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
EOF
  } >"$work/permissions_$name.xml"
  install_document "$work/permissions_$name.xml" "$out/permissions_$name.xml" "$out/permissions_$name.p7s"
done
