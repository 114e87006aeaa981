// The EDS/DCF reader (CiA 306) fed hostile files, and the drive plan checked against what it read:
// a file from a vendor or a user is input like any other.
//
// Properties (docs/fuzzing.md):
// - parse() returns or throws mrroc::ConfigError, whose text names "file:line" (or the file);
//   nothing else escapes, nothing crashes;
// - every entry read has a type mrroc knows, and its value (when it has one and is a number)
//   fits the type's width, as the reader promises;
// - plan_drive() on what was read returns or throws mrroc::ConfigErrors; a plan's PDOs hold at
//   most 64 bits of entries.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_common.hpp"
#include "mrroc/can/drive_setup.hpp"
#include "mrroc/can/eds.hpp"
#include "mrroc/config/check.hpp"

// drive_setup.cpp's built-in file (the generated default_eds.cpp), not needed here.
namespace mrroc::can {
extern const char* const kDefaultDriveEdsText;
extern const char* const kDefaultDriveEdsName;
const char* const kDefaultDriveEdsText = "";
const char* const kDefaultDriveEdsName = "none";
}  // namespace mrroc::can

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mrroc::can;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::shared_ptr<const eds::Dictionary> d;
  try {
    d = std::make_shared<eds::Dictionary>(eds::Dictionary::parse(text, "fuzz.eds"));
  } catch (const mrroc::ConfigError& e) {
    fuzz::expect(std::string_view(e.what()).rfind("fuzz.eds", 0) == 0,
                 std::string("an error that does not name the file: ") + e.what());
    return 0;
  }
  for (const auto& [index, object] : d->objects())
    for (const auto& [sub, entry] : object.entries) {
      const int bits = eds::bit_size(entry.data_type);
      fuzz::expect(bits >= 0, "an entry of an unknown type was accepted");
      if (entry.value && !eds::is_string(entry.data_type) && bits > 0 && bits < 64 &&
          !entry.value->plus_node_id)
        fuzz::expect((entry.value->raw >> bits) == 0U, "a value wider than its type");
    }
  DriveRequest request;
  request.node = 5;
  request.axis = "fuzz";
  try {
    const DrivePlan plan = plan_drive(d, request);
    for (const auto* list : {&plan.rpdos, &plan.tpdos})
      for (const PdoPlan& p : *list) {
        int total = 0;
        for (const PdoEntry& e : p.entries) total += e.bits;
        fuzz::expect(total <= 64, "a planned PDO longer than 64 bits");
      }
  } catch (const mrroc::ConfigErrors&) {
  }
  return 0;
}
