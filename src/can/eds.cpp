/// @file
/// The EDS/DCF reader (see eds.hpp).
#include "mrroc/can/eds.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unordered_map>

namespace mrroc::can::eds {

int bit_size(std::uint16_t t) noexcept {
  switch (t) {
    case type::kBoolean: return 1;
    case type::kInteger8:
    case type::kUnsigned8: return 8;
    case type::kInteger16:
    case type::kUnsigned16: return 16;
    case type::kInteger24:
    case type::kUnsigned24: return 24;
    case type::kInteger32:
    case type::kUnsigned32:
    case type::kReal32: return 32;
    case type::kInteger64:
    case type::kUnsigned64:
    case type::kReal64: return 64;
    case type::kVisibleString:
    case type::kOctetString:
    case type::kUnicodeString:
    case type::kDomain: return 0;
    default: return -1;
  }
}

bool is_signed(std::uint16_t t) noexcept {
  return t == type::kInteger8 || t == type::kInteger16 || t == type::kInteger24 ||
         t == type::kInteger32 || t == type::kInteger64;
}

bool is_string(std::uint16_t t) noexcept {
  return t == type::kVisibleString || t == type::kOctetString || t == type::kUnicodeString ||
         t == type::kDomain;
}

std::string_view type_name(std::uint16_t t) noexcept {
  switch (t) {
    case type::kBoolean: return "BOOLEAN";
    case type::kInteger8: return "INTEGER8";
    case type::kInteger16: return "INTEGER16";
    case type::kInteger24: return "INTEGER24";
    case type::kInteger32: return "INTEGER32";
    case type::kInteger64: return "INTEGER64";
    case type::kUnsigned8: return "UNSIGNED8";
    case type::kUnsigned16: return "UNSIGNED16";
    case type::kUnsigned24: return "UNSIGNED24";
    case type::kUnsigned32: return "UNSIGNED32";
    case type::kUnsigned64: return "UNSIGNED64";
    case type::kReal32: return "REAL32";
    case type::kReal64: return "REAL64";
    case type::kVisibleString: return "VISIBLE_STRING";
    case type::kOctetString: return "OCTET_STRING";
    case type::kUnicodeString: return "UNICODE_STRING";
    case type::kDomain: return "DOMAIN";
    default: return "unknown";
  }
}

std::string_view to_string(Access a) noexcept {
  switch (a) {
    case Access::ro: return "ro";
    case Access::wo: return "wo";
    case Access::rw: return "rw";
    case Access::rwr: return "rwr";
    case Access::rww: return "rww";
    case Access::constant: return "const";
  }
  return "?";
}

std::uint32_t mode_bit(std::int8_t m) noexcept {
  return m >= 1 && m <= 10 ? (1U << static_cast<unsigned>(m - 1)) : 0U;
}

std::string_view mode_name(std::int8_t m) noexcept {
  switch (m) {
    case mode::kProfilePosition: return "profile position";
    case 2: return "velocity";
    case mode::kProfileVelocity: return "profile velocity";
    case 4: return "profile torque";
    case mode::kHoming: return "homing";
    case mode::kInterpolatedPosition: return "interpolated position";
    case mode::kCyclicSyncPosition: return "cyclic synchronous position";
    case mode::kCyclicSyncVelocity: return "cyclic synchronous velocity";
    case mode::kCyclicSyncTorque: return "cyclic synchronous torque";
    default: return "manufacturer-specific or unknown";
  }
}

std::int64_t as_signed(const Entry& e, std::uint64_t raw) noexcept {
  const int bits = bit_size(e.data_type);
  if (!is_signed(e.data_type) || bits <= 0 || bits >= 64) return static_cast<std::int64_t>(raw);
  const std::uint64_t sign = 1ULL << static_cast<unsigned>(bits - 1);
  const std::uint64_t mask = (1ULL << static_cast<unsigned>(bits)) - 1U;
  raw &= mask;
  return (raw & sign) != 0U ? static_cast<std::int64_t>(raw | ~mask)
                            : static_cast<std::int64_t>(raw);
}

std::optional<std::string> out_of_range(const Entry& e, std::uint64_t raw) {
  const int bits = bit_size(e.data_type);
  if (bits > 0 && bits < 64 && (raw >> static_cast<unsigned>(bits)) != 0U)
    return "wider than " + std::to_string(bits) + " bits (" + std::string(type_name(e.data_type)) +
           ")";
  if (e.data_type == type::kReal32 || e.data_type == type::kReal64) return std::nullopt;
  const bool big_unsigned = !is_signed(e.data_type) && bits == 64;
  const std::int64_t v = as_signed(e, raw);
  if (e.low_limit && !big_unsigned && v < *e.low_limit)
    return std::to_string(v) + " below the low limit " + std::to_string(*e.low_limit);
  if (e.high_limit &&
      (big_unsigned ? raw > static_cast<std::uint64_t>(*e.high_limit) : v > *e.high_limit))
    return std::to_string(v) + " above the high limit " + std::to_string(*e.high_limit);
  return std::nullopt;
}

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

struct Key {
  std::string value;
  int line = 0;
};
struct Section {
  std::string name;  ///< as written
  int line = 0;
  std::unordered_map<std::string, Key> keys;  ///< by lower-case key
  [[nodiscard]] const Key* get(const char* key) const {
    const auto it = keys.find(key);
    return it == keys.end() ? nullptr : &it->second;
  }
};

bool is_hex(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return std::isxdigit(static_cast<unsigned char>(c)) != 0;
  });
}

std::uint32_t hex_of(std::string_view s) {
  std::uint32_t v = 0;
  std::from_chars(s.data(), s.data() + s.size(), v, 16);
  return v;
}

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(int line, const std::string& message) const {
    throw ConfigError(SourceLocation{file_, line}, message);
  }

  /// An unsigned integer in decimal, 0x hexadecimal or octal, optionally negative: the value
  /// as a signed 128-bit-free pair (magnitude, negative).
  std::pair<std::uint64_t, bool> integer(std::string_view text, int line,
                                         const std::string& what) const {
    std::string_view s = trim(text);
    bool negative = false;
    if (!s.empty() && (s.front() == '-' || s.front() == '+')) {
      negative = s.front() == '-';
      s.remove_prefix(1);
    }
    int base = 10;
    if (s.size() > 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) {
      base = 16;
      s.remove_prefix(2);
    } else if (s.size() > 1 && s[0] == '0') {
      base = 8;
      s.remove_prefix(1);
    }
    std::uint64_t v = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v, base);
    if (s.empty() || ec != std::errc() || end != s.data() + s.size())
      fail(line, what + " '" + std::string(trim(text)) + "' is not a number (decimal, 0x hex or " +
                     "octal)");
    return {v, negative};
  }

  /// A value of `data_type` as written (DefaultValue, ParameterValue, limits).
  Value value(std::string_view text, std::uint16_t data_type, int line,
              const std::string& what) const {
    Value out;
    out.line = line;
    if (is_string(data_type)) {
      out.text = std::string(text);
      return out;
    }
    const int bits = bit_size(data_type);
    if (data_type == type::kReal32 || data_type == type::kReal64) {
      const std::string s(trim(text));
      char* end = nullptr;
      const double d = std::strtod(s.c_str(), &end);
      if (s.empty() || end != s.c_str() + s.size())
        fail(line, what + " '" + s + "' is not a number");
      if (data_type == type::kReal32) {
        const auto f = static_cast<float>(d);
        std::uint32_t b = 0;
        std::memcpy(&b, &f, sizeof b);
        out.raw = b;
      } else {
        std::memcpy(&out.raw, &d, sizeof out.raw);
      }
      return out;
    }
    // Terms joined by '+': numbers and at most one $NODEID.
    std::uint64_t sum = 0;
    bool negative_sum = false;
    std::string_view rest = text;
    bool any = false;
    while (true) {
      const std::size_t plus = rest.find('+', 1);  // a leading '+' is a sign
      const std::string_view term = trim(rest.substr(0, plus));
      if (lower(term) == "$nodeid") {
        if (out.plus_node_id) fail(line, what + " '" + std::string(text) + "' adds $NODEID twice");
        out.plus_node_id = true;
      } else {
        const auto [v, negative] = integer(term, line, what);
        if (negative) {
          if (any || negative_sum)
            fail(line,
                 what + " '" + std::string(text) + "': a negative " + "number must stand alone");
          negative_sum = true;
        }
        sum += v;
      }
      any = true;
      if (plus == std::string_view::npos) break;
      rest.remove_prefix(plus + 1);
    }
    const std::string type_text = " (" + std::string(type_name(data_type)) + ")";
    if (negative_sum) {
      const std::uint64_t limit = is_signed(data_type) && bits > 0
                                      ? (bits >= 64 ? (1ULL << 63U) : (1ULL << (bits - 1)))
                                      : 0;
      if (sum > limit || (!is_signed(data_type) && sum != 0))
        fail(line, what + " '" + std::string(trim(text)) + "' is out of range" + type_text);
      out.raw = static_cast<std::uint64_t>(-static_cast<std::int64_t>(sum - 1) - 1);
      if (bits < 64) out.raw &= (1ULL << static_cast<unsigned>(bits)) - 1U;
      return out;
    }
    if (bits > 0 && bits < 64 && (sum >> static_cast<unsigned>(bits)) != 0U)
      fail(line, what + " '" + std::string(trim(text)) + "' does not fit in " +
                     std::to_string(bits) + " bits" + type_text);
    out.raw = sum;
    return out;
  }

  std::uint16_t data_type(const Section& s, int line_of_object) const {
    const Key* k = s.get("datatype");
    if (k == nullptr) fail(line_of_object, "[" + s.name + "] has no DataType");
    const auto [v, negative] = integer(k->value, k->line, "DataType");
    if (negative || v > 0xFFFF || bit_size(static_cast<std::uint16_t>(v)) < 0)
      fail(k->line, "DataType " + std::string(trim(k->value)) +
                        " is not a CiA 301 data type mrroc knows (0x0001..0x001B basic types)");
    return static_cast<std::uint16_t>(v);
  }

  Access access(const Section& s, int line_of_object) const {
    const Key* k = s.get("accesstype");
    if (k == nullptr) fail(line_of_object, "[" + s.name + "] has no AccessType");
    const std::string a = lower(trim(k->value));
    if (a == "ro") return Access::ro;
    if (a == "wo") return Access::wo;
    if (a == "rw") return Access::rw;
    if (a == "rwr") return Access::rwr;
    if (a == "rww") return Access::rww;
    if (a == "const") return Access::constant;
    fail(k->line,
         "AccessType '" + std::string(trim(k->value)) + "' is none of ro, wo, rw, rwr, rww, const");
  }

  bool flag(const Section& s, const char* key) const {
    const Key* k = s.get(key);
    if (k == nullptr || trim(k->value).empty()) return false;
    const auto [v, negative] = integer(k->value, k->line, k == nullptr ? "" : key);
    if (negative || v > 1) fail(k->line, std::string(key) + " must be 0 or 1");
    return v == 1;
  }

  /// The entry described by the keys of `s` (a VAR's section or a sub-object's).
  Entry entry(const Section& s, std::uint16_t index, std::uint8_t sub) const {
    Entry e;
    e.index = index;
    e.sub = sub;
    e.line = s.line;
    if (const Key* k = s.get("parametername")) e.name = std::string(trim(k->value));
    e.data_type = data_type(s, s.line);
    e.access = access(s, s.line);
    e.pdo_mappable = flag(s, "pdomapping");
    const auto limit = [&](const char* key) -> std::optional<std::int64_t> {
      const Key* k = s.get(key);
      if (k == nullptr || trim(k->value).empty() || is_string(e.data_type) ||
          e.data_type == type::kReal32 || e.data_type == type::kReal64)
        return std::nullopt;
      const Value v =
          value(k->value, e.data_type, k->line, s.get("lowlimit") == k ? "LowLimit" : "HighLimit");
      return as_signed(e, v.raw);
    };
    e.low_limit = limit("lowlimit");
    e.high_limit = limit("highlimit");
    for (const char* key : {"parametervalue", "defaultvalue"}) {
      const Key* k = s.get(key);
      if (k == nullptr || (trim(k->value).empty() && !is_string(e.data_type))) continue;
      e.value = value(k->value, e.data_type, k->line,
                      std::strcmp(key, "parametervalue") == 0 ? "ParameterValue" : "DefaultValue");
      if (!e.value->plus_node_id && !is_string(e.data_type))
        if (const auto why = out_of_range(e, e.value->raw))
          fail(k->line, std::string(std::strcmp(key, "parametervalue") == 0 ? "ParameterValue"
                                                                            : "DefaultValue") +
                            " of " + hex_name(index, sub) + ": " + *why);
      break;
    }
    return e;
  }

  static std::string hex_name(std::uint16_t index, std::uint8_t sub) {
    char b[24];
    std::snprintf(b, sizeof b, "0x%04X sub %u", index, sub);
    return b;
  }

  std::string file_;
};

}  // namespace

const Object* Dictionary::object(std::uint16_t index) const noexcept {
  const auto it = objects_.find(index);
  return it == objects_.end() ? nullptr : &it->second;
}

const Entry* Dictionary::entry(std::uint16_t index, std::uint8_t sub) const noexcept {
  const Object* o = object(index);
  if (o == nullptr) return nullptr;
  const auto it = o->entries.find(sub);
  return it == o->entries.end() ? nullptr : &it->second;
}

std::optional<std::uint64_t> Dictionary::value(std::uint16_t index, std::uint8_t sub,
                                               std::uint8_t node) const noexcept {
  const Entry* e = entry(index, sub);
  if (e == nullptr || !e->value || is_string(e->data_type)) return std::nullopt;
  return e->value->raw + (e->value->plus_node_id ? node : 0U);
}

std::uint32_t Dictionary::supported_modes() const noexcept {
  const auto v = value(0x6502, 0, 0);
  return v ? static_cast<std::uint32_t>(*v) : 0U;
}

Dictionary Dictionary::load(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw ConfigError(SourceLocation::whole_file(path.string()),
                      "cannot read the EDS/DCF file: " + std::string(std::strerror(errno)));
  std::ostringstream text;
  text << in.rdbuf();
  return parse(text.str(), path.string());
}

Dictionary Dictionary::parse(std::string_view text, std::string file) {
  Reader r(file);
  std::vector<Section> sections;
  std::unordered_map<std::string, std::size_t> by_name;
  int line_no = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view raw = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    const std::string_view line = trim(raw);
    if (line.empty() || line.front() == ';' || line.front() == '#') continue;
    if (line.front() == '[') {
      if (line.back() != ']') r.fail(line_no, "section header without ']'");
      const std::string name(trim(line.substr(1, line.size() - 2)));
      if (name.empty()) r.fail(line_no, "empty section name");
      const std::string key = lower(name);
      if (const auto it = by_name.find(key); it != by_name.end())
        r.fail(line_no, "section [" + name + "] appears twice (first at line " +
                            std::to_string(sections[it->second].line) + ")");
      by_name.emplace(key, sections.size());
      sections.push_back(Section{name, line_no, {}});
      continue;
    }
    const std::size_t eq = line.find('=');
    if (eq == std::string_view::npos)
      r.fail(line_no, "'" + std::string(line.substr(0, 40)) + "' is neither a [section] nor a " +
                          "key=value line");
    if (sections.empty()) r.fail(line_no, "a key before the first [section]");
    const std::string key = lower(trim(line.substr(0, eq)));
    if (key.empty()) r.fail(line_no, "a line with '=' but no key");
    Section& s = sections.back();
    if (const auto it = s.keys.find(key); it != s.keys.end())
      r.fail(line_no, "key '" + std::string(trim(line.substr(0, eq))) + "' appears twice in [" +
                          s.name + "] (first at line " + std::to_string(it->second.line) + ")");
    s.keys.emplace(key, Key{std::string(trim(line.substr(eq + 1))), line_no});
  }

  Dictionary d;
  d.file_ = file;
  const auto section = [&](const std::string& lower_name) -> const Section* {
    const auto it = by_name.find(lower_name);
    return it == by_name.end() ? nullptr : &sections[it->second];
  };
  const auto number = [&](const Section& s, const char* key, std::uint64_t max) -> std::uint64_t {
    const Key* k = s.get(key);
    if (k == nullptr || trim(k->value).empty()) return 0;
    const auto [v, negative] = r.integer(k->value, k->line, k == nullptr ? "" : key);
    if (negative || v > max)
      r.fail(k->line,
             std::string(key) + " " + k->value + " is out of range 0.." + std::to_string(max));
    return v;
  };
  if (const Section* info = section("deviceinfo")) {
    if (const Key* k = info->get("vendorname")) d.device_.vendor_name = k->value;
    if (const Key* k = info->get("productname")) d.device_.product_name = k->value;
    d.device_.vendor_number = static_cast<std::uint32_t>(number(*info, "vendornumber", 0xFFFFFFFF));
    d.device_.product_number =
        static_cast<std::uint32_t>(number(*info, "productnumber", 0xFFFFFFFF));
    d.device_.revision_number =
        static_cast<std::uint32_t>(number(*info, "revisionnumber", 0xFFFFFFFF));
    d.device_.rx_pdos = static_cast<int>(number(*info, "nrofrxpdo", 512));
    d.device_.tx_pdos = static_cast<int>(number(*info, "nroftxpdo", 512));
    for (const int rate : {10, 20, 50, 125, 250, 500, 800, 1000}) {
      const std::string key = "baudrate_" + std::to_string(rate);
      if (number(*info, key.c_str(), 1) == 1) d.device_.baud_rates_kbit.push_back(rate);
    }
  }
  if (const Section* dcf = section("devicecomissioning")) {
    if (const Key* k = dcf->get("nodeid"); k != nullptr && !trim(k->value).empty()) {
      const auto [v, negative] = r.integer(k->value, k->line, "NodeID");
      if (negative || v < 1 || v > 127)
        r.fail(k->line, "NodeID " + k->value + " is outside 1..127");
      d.node_id_ = static_cast<std::uint8_t>(v);
    }
  }

  // Objects, then their sub-objects.
  for (const Section& s : sections) {
    const std::string name = lower(s.name);
    if (name.size() != 4 || !is_hex(name)) continue;
    Object o;
    o.index = static_cast<std::uint16_t>(hex_of(name));
    o.line = s.line;
    if (const Key* k = s.get("parametername")) o.name = std::string(trim(k->value));
    o.object_type = static_cast<std::uint8_t>(number(s, "objecttype", 0xFF));
    if (s.get("objecttype") == nullptr) o.object_type = kVar;
    if (o.object_type == kVar) {
      o.entries.emplace(0, r.entry(s, o.index, 0));
    } else if (o.object_type == kArray || o.object_type == kRecord) {
      const std::uint64_t compact = number(s, "compactsubobj", 254);
      if (compact != 0) {
        Entry count;
        count.index = o.index;
        count.name = "Number of entries";
        count.data_type = type::kUnsigned8;
        count.access = Access::ro;
        count.line = s.line;
        count.value = Value{compact, false, {}, s.line};
        o.entries.emplace(0, count);
        const Section* names = section(name + "name");
        const Section* values = section(name + "value");
        for (std::uint64_t k = 1; k <= compact; ++k) {
          Entry e = r.entry(s, o.index, static_cast<std::uint8_t>(k));
          e.value.reset();
          const std::string key = std::to_string(k);
          e.name = o.name + " " + key;
          if (names != nullptr)
            if (const Key* n = names->get(key.c_str())) e.name = n->value;
          if (const Key* dv = s.get("defaultvalue"); dv != nullptr && !trim(dv->value).empty())
            e.value = r.value(dv->value, e.data_type, dv->line, "DefaultValue");
          if (values != nullptr)
            if (const Key* v = values->get(key.c_str()))
              e.value = r.value(v->value, e.data_type, v->line, "value " + key);
          o.entries.emplace(static_cast<std::uint8_t>(k), e);
        }
      }
    } else {
      r.fail(s.get("objecttype") != nullptr ? s.get("objecttype")->line : s.line,
             "ObjectType " + std::to_string(o.object_type) + " of [" + s.name +
                 "]: mrroc reads VAR (0x7), ARRAY (0x8) and RECORD (0x9)");
    }
    d.objects_.emplace(o.index, std::move(o));
  }
  for (const Section& s : sections) {
    const std::string name = lower(s.name);
    if (name.size() < 8 || name.substr(4, 3) != "sub" || !is_hex(name.substr(0, 4)) ||
        !is_hex(name.substr(7)) || name.size() > 9)
      continue;
    const auto index = static_cast<std::uint16_t>(hex_of(name.substr(0, 4)));
    const auto sub = static_cast<std::uint8_t>(hex_of(name.substr(7)));
    const auto it = d.objects_.find(index);
    if (it == d.objects_.end())
      r.fail(s.line, "[" + s.name + "] belongs to no object: the file has no [" +
                         std::string(s.name.substr(0, 4)) + "]");
    Object& o = it->second;
    if (o.object_type == kVar)
      r.fail(s.line, "[" + s.name + "]: object 0x" + std::string(s.name.substr(0, 4)) +
                         " is a VAR, which has no sub-objects");
    if (o.entries.count(sub) != 0)
      r.fail(s.line, "[" + s.name + "]: sub-index " + std::to_string(sub) +
                         " is given twice (CompactSubObj and a section?)");
    o.entries.emplace(sub, r.entry(s, index, sub));
  }
  for (const Section& s : sections) {
    const std::string name = lower(s.name);
    if (name.size() != 4 || !is_hex(name)) continue;
    const Object& o = d.objects_.at(static_cast<std::uint16_t>(hex_of(name)));
    if (o.object_type == kVar) continue;
    if (const Key* k = s.get("subnumber"); k != nullptr && s.get("compactsubobj") == nullptr) {
      const std::uint64_t n = number(s, "subnumber", 255);
      if (n != o.entries.size())
        r.fail(k->line, "SubNumber " + std::to_string(n) + " of [" + s.name +
                            "], but the file has " + std::to_string(o.entries.size()) + " [" +
                            s.name + "subN] sections");
    }
    if (o.entries.empty())
      r.fail(s.line, "[" + s.name + "] is an ARRAY or RECORD without sub-objects (no SubNumber " +
                         "sections, no CompactSubObj)");
  }
  // The object lists.
  for (const char* list : {"mandatoryobjects", "optionalobjects", "manufacturerobjects"}) {
    const Section* s = section(list);
    if (s == nullptr) continue;
    const std::uint64_t count = number(*s, "supportedobjects", 0xFFFF);
    for (std::uint64_t k = 1; k <= count; ++k) {
      const Key* entry = s->get(std::to_string(k).c_str());
      if (entry == nullptr)
        r.fail(s->line, "[" + s->name + "] lists " + std::to_string(count) +
                            " objects but has no entry " + std::to_string(k));
      const auto [v, negative] = r.integer(entry->value, entry->line, "object index");
      if (negative || v > 0xFFFF) r.fail(entry->line, "object index out of range 0..0xFFFF");
      if (d.objects_.count(static_cast<std::uint16_t>(v)) == 0) {
        char b[8];
        std::snprintf(b, sizeof b, "%04X", static_cast<unsigned>(v));
        r.fail(entry->line,
               "[" + s->name + "] lists object 0x" + b + ", which has no [" + b + "] section");
      }
    }
  }
  return d;
}

}  // namespace mrroc::can::eds
