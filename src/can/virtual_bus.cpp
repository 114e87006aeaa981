// The virtual CAN bus: a broadcast ring in POSIX shared memory (see virtual_bus.hpp).
//
// Memory ordering. Every field of the shared object is a lock-free std::atomic, so concurrent
// writers and readers (threads or processes) never race in the C++ sense; ThreadSanitizer sees
// that. The ordering rules:
//  - a slot's `seq` is 0 (never written), publish(i) = (i + 1) << 1 when it holds ring position i,
//    or publish(i) | 1 while a sender writes position i into it;
//  - a sender takes the slot with a CAS of `seq` to busy(i), then stores the fields with release
//    (so a reader that sees any of the new fields also sees busy(i)), then CASes busy(i) to
//    publish(i) with release;
//  - a reader loads `seq` with acquire, the fields with acquire, `seq` again, and keeps the frame
//    only when both loads gave publish(i) and the check word matches the fields: a sender that
//    was lapped (the ring wrapped while it was stalled between claim and publish) may still store
//    stale fields into a slot that a newer sender has published, and the check word (a hash of
//    the position and the fields) exposes such a mix;
//  - futex wake-ups: a sender increments `publish_count` after publishing and wakes the futex
//    when `waiters` is non-zero; a reader increments `waiters`, reads `publish_count`, checks
//    the ring again and sleeps only while `publish_count` is unchanged (all four seq_cst, so
//    either the reader sees the frame or the sender sees the waiter).
#include "virtual_bus.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <linux/futex.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <new>
#include <vector>

#include "mrroc/core/error.hpp"

namespace mrroc::can::detail {

namespace {

constexpr std::uint64_t kMagic = 0x4e41434352524d4dULL;  // "MMRRCCAN" little-endian
constexpr std::uint32_t kVersion = 1;
constexpr std::uint64_t kSlotMask = kVirtualBusSlots - 1;
static_assert((kVirtualBusSlots & kSlotMask) == 0, "the ring size must be a power of two");

static_assert(std::atomic<std::uint64_t>::is_always_lock_free &&
                  std::atomic<std::uint32_t>::is_always_lock_free &&
                  std::atomic<std::int64_t>::is_always_lock_free,
              "shared-memory atomics must be lock-free (they are shared between processes)");
static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t),
              "the futex word must be a plain 32-bit integer");

/// One frame of the ring; one cache line, so that senders of neighbouring slots do not share one.
struct alignas(64) Slot {
  std::atomic<std::uint64_t> seq;
  std::atomic<std::uint64_t> head;  // can_id, len, __pad, __res0, len8_dlc (can_frame bytes 0-7)
  std::atomic<std::uint64_t> data;  // can_frame bytes 8-15
  std::atomic<std::int64_t> timestamp_ns;
  std::atomic<std::uint64_t> sender;
  std::atomic<std::uint64_t> check;
};
static_assert(sizeof(Slot) == 64);

struct alignas(64) Header {
  std::atomic<std::uint64_t> magic;  // stored last when the object is initialised
  std::uint32_t version;
  std::uint32_t slot_count;
  std::uint32_t slot_size;
  std::uint32_t header_size;
  std::uint64_t total_size;
  alignas(64) std::atomic<std::uint64_t> write_index;    // next ring position to claim
  alignas(64) std::atomic<std::uint32_t> publish_count;  // the futex word
  std::atomic<std::uint32_t> waiters;  // nodes sleeping on it (a node that died asleep stays)
  alignas(64) std::atomic<std::uint64_t> next_node;  // node ids, unique per bus
};

struct Shared {
  Header header;
  Slot slots[kVirtualBusSlots];
};
constexpr std::size_t kSharedSize = sizeof(Shared);

constexpr std::uint64_t published(std::uint64_t index) { return (index + 1) << 1; }
constexpr std::uint64_t busy(std::uint64_t index) { return published(index) | 1U; }
/// The ring position a `seq` value refers to, plus one (0: never written).
constexpr std::uint64_t position_plus_one(std::uint64_t seq) { return seq >> 1; }

std::uint64_t mix(std::uint64_t h, std::uint64_t v) {
  h ^= v + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
  h ^= h >> 31;
  h *= 0xbf58476d1ce4e5b9ULL;
  h ^= h >> 29;
  return h;
}
std::uint64_t check_word(std::uint64_t index, std::uint64_t head, std::uint64_t data,
                         std::int64_t timestamp_ns, std::uint64_t sender) {
  std::uint64_t h = mix(0x6d72726f63616e31ULL, index);
  h = mix(h, head);
  h = mix(h, data);
  h = mix(h, static_cast<std::uint64_t>(timestamp_ns));
  return mix(h, sender);
}

std::int64_t clock_ns(clockid_t clock) {
  timespec t{};
  clock_gettime(clock, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000LL + t.tv_nsec;
}

std::uint32_t* futex_word(Shared* shared) {
  // std::atomic<uint32_t> is a plain 32-bit integer in memory (static_assert above).
  return reinterpret_cast<std::uint32_t*>(&shared->header.publish_count);
}

void futex_wake_all(Shared* shared) {
  // Not FUTEX_PRIVATE_FLAG: the word is shared between processes.
  syscall(SYS_futex, futex_word(shared), FUTEX_WAKE, INT_MAX, nullptr, nullptr, 0);
}

void futex_wait(Shared* shared, std::uint32_t expected, std::int64_t timeout_ns) {
  timespec t{};
  t.tv_sec = static_cast<time_t>(timeout_ns / 1'000'000'000LL);
  t.tv_nsec = static_cast<long>(timeout_ns % 1'000'000'000LL);
  syscall(SYS_futex, futex_word(shared), FUTEX_WAIT, expected, &t, nullptr, 0);
}

std::string errno_text(int error) { return std::string(std::strerror(error)); }

// ---- The mapping of one bus, shared by every node of it in this process ----

/// One mmap of the shared object per process and bus (every Bus object of the process that opens
/// the same bus uses it), so that ThreadSanitizer sees one address for one atomic.
class Mapping {
 public:
  Mapping(Shared* shared, dev_t device, ino_t inode)
      : shared_(shared), device_(device), inode_(inode) {}
  Mapping(const Mapping&) = delete;
  Mapping& operator=(const Mapping&) = delete;
  ~Mapping() { munmap(shared_, kSharedSize); }
  [[nodiscard]] Shared* shared() const { return shared_; }
  [[nodiscard]] bool same_object(const struct stat& s) const {
    return s.st_dev == device_ && s.st_ino == inode_;
  }

 private:
  Shared* shared_;
  dev_t device_;
  ino_t inode_;
};

/// Closes a file descriptor when the scope ends.
class FileDescriptor {
 public:
  explicit FileDescriptor(int fd) : fd_(fd) {}
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  ~FileDescriptor() {
    if (fd_ >= 0) ::close(fd_);
  }
  [[nodiscard]] int get() const { return fd_; }

 private:
  int fd_;
};

void initialise(Shared* shared) {
  auto* fresh = new (shared) Shared();  // value-initialised: every atomic 0
  Header& h = fresh->header;
  h.version = kVersion;
  h.slot_count = kVirtualBusSlots;
  h.slot_size = sizeof(Slot);
  h.header_size = sizeof(Header);
  h.total_size = kSharedSize;
  h.next_node.store(1, std::memory_order_relaxed);
  h.magic.store(kMagic, std::memory_order_release);
}

std::shared_ptr<Mapping> map_bus(std::string_view url, std::string_view name) {
  static std::mutex registry_mutex;
  static std::map<std::string, std::weak_ptr<Mapping>, std::less<>> registry;

  const std::string object = virtual_bus_object(name);
  const std::string path = "/dev/shm" + object;
  const std::string where = std::string(url) + ": " + path;
  // Only this user's processes share a bus: a frame on it can move a robot.
  FileDescriptor fd(shm_open(object.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600));
  if (fd.get() < 0)
    throw HardwareError(where + ": cannot open the shared-memory object: " + errno_text(errno));
  struct stat st {};
  if (fstat(fd.get(), &st) != 0) throw HardwareError(where + ": fstat: " + errno_text(errno));
  if (st.st_uid != geteuid())
    throw HardwareError(
        fmt::format("{}: the shared-memory object belongs to user {}, not to this "
                    "process' user {}: refusing a bus others can write to",
                    where, st.st_uid, geteuid()));
  if ((st.st_mode & 0077) != 0 && fchmod(fd.get(), 0600) != 0)
    throw HardwareError(
        where + ": cannot make the shared-memory object private (mode 0600): " + errno_text(errno));

  std::lock_guard lock(registry_mutex);
  if (auto it = registry.find(object); it != registry.end()) {
    if (auto mapping = it->second.lock(); mapping && mapping->same_object(st)) return mapping;
  }

  // flock serialises creation and the header check between processes; the kernel drops the
  // lock of a process that dies, so a creator that crashed half-way cannot block the others.
  while (flock(fd.get(), LOCK_EX) != 0)
    if (errno != EINTR) throw HardwareError(where + ": flock: " + errno_text(errno));
  if (fstat(fd.get(), &st) != 0) throw HardwareError(where + ": fstat: " + errno_text(errno));
  const auto size = static_cast<std::uint64_t>(st.st_size);
  if (size == 0) {
    if (ftruncate(fd.get(), static_cast<off_t>(kSharedSize)) != 0)
      throw HardwareError(where + ": cannot size the shared-memory object to " +
                          std::to_string(kSharedSize) + " bytes: " + errno_text(errno));
  } else if (size != kSharedSize) {
    throw HardwareError(where + ": the existing shared-memory object has " + std::to_string(size) +
                        " bytes, this mrroc expects " + std::to_string(kSharedSize) +
                        " (left by another mrroc version?); stop the processes using the bus "
                        "and remove the file");
  }
  void* address = mmap(nullptr, kSharedSize, PROT_READ | PROT_WRITE, MAP_SHARED, fd.get(), 0);
  if (address == MAP_FAILED)  // NOLINT(performance-no-int-to-ptr)
    throw HardwareError(where + ": mmap of " + std::to_string(kSharedSize) +
                        " bytes: " + errno_text(errno));
  auto* shared = std::launder(static_cast<Shared*>(address));
  const std::uint64_t magic = shared->header.magic.load(std::memory_order_acquire);
  if (magic == 0) {
    // New, or its creator died before finishing (it held the lock we hold now).
    initialise(shared);
  } else if (magic != kMagic || shared->header.version != kVersion ||
             shared->header.slot_count != kVirtualBusSlots ||
             shared->header.slot_size != sizeof(Slot) ||
             shared->header.header_size != sizeof(Header) ||
             shared->header.total_size != kSharedSize) {
    munmap(address, kSharedSize);
    char found[160];
    std::snprintf(found, sizeof found, "magic %#llx, version %u, %u slots of %u bytes",
                  static_cast<unsigned long long>(magic), shared->header.version,
                  shared->header.slot_count, shared->header.slot_size);
    throw HardwareError(where + ": the existing shared-memory object has another layout (" + found +
                        "; expected version " + std::to_string(kVersion) + ", " +
                        std::to_string(kVirtualBusSlots) + " slots of " +
                        std::to_string(sizeof(Slot)) +
                        " bytes); stop the processes using the bus and remove the file");
  }
  flock(fd.get(), LOCK_UN);
  auto mapping = std::make_shared<Mapping>(shared, st.st_dev, st.st_ino);
  registry[object] = mapping;
  return mapping;
}

// ---- One node ----

class VirtualBus final : public Bus {
 public:
  VirtualBus(std::string url, std::shared_ptr<Mapping> mapping)
      : url_(std::move(url)), mapping_(std::move(mapping)), shared_(mapping_->shared()) {
    node_ = shared_->header.next_node.fetch_add(1, std::memory_order_relaxed);
    read_index_ = shared_->header.write_index.load(std::memory_order_acquire);
    filters_.push_back(can_filter{0, 0});  // as CAN_RAW: everything passes until set_filters
  }

  [[nodiscard]] std::string url() const override { return url_; }

  SendResult send(const can_frame& frame) noexcept override {
    if (frame.len > CAN_MAX_DLEN) {
      ++stats_.send_failures;
      std::snprintf(last_error_, sizeof last_error_,
                    "%s: send: frame 0x%x has %u data bytes, a classical CAN frame at most %d",
                    url_.c_str(), frame.can_id, static_cast<unsigned>(frame.len), CAN_MAX_DLEN);
      return SendResult::error;
    }
    std::uint64_t head = 0;
    std::uint64_t data = 0;
    static_assert(sizeof(can_frame) == 2 * sizeof(std::uint64_t));
    std::memcpy(&head, &frame, sizeof head);
    std::memcpy(&data, frame.data, sizeof data);
    const std::int64_t stamp = clock_ns(CLOCK_REALTIME);
    Header& h = shared_->header;
    const std::uint64_t index = h.write_index.fetch_add(1, std::memory_order_relaxed);
    const bool ok = write_slot(index, head, data, stamp);
    h.publish_count.fetch_add(1, std::memory_order_seq_cst);
    if (h.waiters.load(std::memory_order_seq_cst) != 0) futex_wake_all(shared_);
    if (!ok) {
      ++stats_.send_failures;
      std::snprintf(last_error_, sizeof last_error_,
                    "%s: send: the ring of %u frames wrapped while frame 0x%x was being written "
                    "(bus flooded); frame dropped",
                    url_.c_str(), kVirtualBusSlots, frame.can_id);
      return SendResult::busy;
    }
    ++stats_.sent;
    return SendResult::sent;
  }

  bool receive(Received& out, std::chrono::nanoseconds timeout) noexcept override {
    // Clamped to 10^15 ns (11.6 days) so that the deadline cannot overflow.
    const std::int64_t timeout_ns =
        std::clamp<std::int64_t>(timeout.count(), 0, 1'000'000'000'000'000LL);
    const std::int64_t deadline = timeout_ns > 0 ? clock_ns(CLOCK_MONOTONIC) + timeout_ns : 0;
    Header& h = shared_->header;
    for (;;) {
      const Poll p = poll(out);
      if (p == Poll::frame) return true;
      if (timeout_ns == 0) return false;
      const std::int64_t now = clock_ns(CLOCK_MONOTONIC);
      if (now >= deadline) return false;
      std::int64_t wait_ns = deadline - now;
      if (p == Poll::pending) wait_ns = std::min(wait_ns, stall_since_ + kVirtualBusStallNs - now);
      if (wait_ns <= 0) continue;
      h.waiters.fetch_add(1, std::memory_order_seq_cst);
      const std::uint32_t seen = h.publish_count.load(std::memory_order_seq_cst);
      if (!something_new(p)) futex_wait(shared_, seen, wait_ns);
      h.waiters.fetch_sub(1, std::memory_order_seq_cst);
    }
  }

  void set_filters(std::span<const can_filter> filters) override {
    if (filters.size() > CAN_RAW_FILTER_MAX)
      throw HardwareError(url_ + ": " + std::to_string(filters.size()) +
                          " receive filters, the limit is " + std::to_string(CAN_RAW_FILTER_MAX) +
                          " (CAN_RAW_FILTER_MAX)");
    filters_.assign(filters.begin(), filters.end());
  }

  void receive_error_frames(bool enable) override { error_mask_ = enable ? CAN_ERR_MASK : 0U; }

  [[nodiscard]] BusStats stats() const noexcept override { return stats_; }
  [[nodiscard]] std::string last_error() const override { return last_error_; }

  void abandon_claim(bool marked) {
    const std::uint64_t index = shared_->header.write_index.fetch_add(1, std::memory_order_relaxed);
    if (!marked) return;
    Slot& slot = shared_->slots[index & kSlotMask];
    std::uint64_t seq = slot.seq.load(std::memory_order_relaxed);
    while (position_plus_one(seq) <= index &&
           !slot.seq.compare_exchange_weak(seq, busy(index), std::memory_order_relaxed)) {
    }
    slot.head.store(0xdeadULL, std::memory_order_release);
  }

 private:
  enum class Poll { frame, empty, pending };

  /// Writes ring position `index`; false when a newer sender took the slot (the ring wrapped).
  bool write_slot(std::uint64_t index, std::uint64_t head, std::uint64_t data, std::int64_t stamp) {
    Slot& slot = shared_->slots[index & kSlotMask];
    std::uint64_t seq = slot.seq.load(std::memory_order_relaxed);
    for (;;) {
      // A slot still marked by an older sender belongs to one that died or stalled for a whole
      // lap of the ring: take it over (its late stores are caught by the check word).
      if (position_plus_one(seq) > index) return false;
      if (slot.seq.compare_exchange_weak(seq, busy(index), std::memory_order_relaxed)) break;
    }
    slot.head.store(head, std::memory_order_release);
    slot.data.store(data, std::memory_order_release);
    slot.timestamp_ns.store(stamp, std::memory_order_release);
    slot.sender.store(node_, std::memory_order_release);
    slot.check.store(check_word(index, head, data, stamp, node_), std::memory_order_release);
    std::uint64_t expected = busy(index);
    return slot.seq.compare_exchange_strong(expected, published(index), std::memory_order_release,
                                            std::memory_order_relaxed);
  }

  void skip(std::uint64_t lost) {
    stats_.overruns += lost;
    read_index_ += lost;
    stall_since_ = -1;
  }

  /// Delivers the next frame that passes the filters, if one is published.
  Poll poll(Received& out) {
    Header& h = shared_->header;
    for (;;) {
      const std::uint64_t written = h.write_index.load(std::memory_order_acquire);
      if (read_index_ >= written) return Poll::empty;
      if (written - read_index_ > kVirtualBusSlots) skip(written - kVirtualBusSlots - read_index_);
      Slot& slot = shared_->slots[read_index_ & kSlotMask];
      const std::uint64_t want = published(read_index_);
      const std::uint64_t seq = slot.seq.load(std::memory_order_acquire);
      if (seq == want) {
        const std::uint64_t head = slot.head.load(std::memory_order_acquire);
        const std::uint64_t data = slot.data.load(std::memory_order_acquire);
        const std::int64_t stamp = slot.timestamp_ns.load(std::memory_order_acquire);
        const std::uint64_t sender = slot.sender.load(std::memory_order_acquire);
        const std::uint64_t check = slot.check.load(std::memory_order_acquire);
        const std::uint64_t again = slot.seq.load(std::memory_order_relaxed);
        if (again != want || check != check_word(read_index_, head, data, stamp, sender)) {
          skip(1);  // overwritten while we read it: the ring wrapped under us
          continue;
        }
        ++read_index_;
        stall_since_ = -1;
        if (sender == node_) continue;  // own frame (CAN_RAW_RECV_OWN_MSGS off)
        can_frame frame{};
        std::memcpy(&frame, &head, sizeof head);
        std::memcpy(frame.data, &data, sizeof data);
        if (!accept(frame)) continue;
        out.frame = frame;
        out.timestamp_ns = stamp;
        return Poll::frame;
      }
      if (position_plus_one(seq) > read_index_ + 1) {
        skip(1);  // already reused for a later lap
        continue;
      }
      // Claimed but not yet published: wait for its sender, but not forever.
      const std::int64_t now = clock_ns(CLOCK_MONOTONIC);
      if (stall_since_ < 0) {
        stall_since_ = now;
      } else if (now - stall_since_ >= kVirtualBusStallNs) {
        skip(1);
        continue;
      }
      return Poll::pending;
    }
  }

  /// Whether the ring changed since `poll` returned `p` (checked before sleeping).
  [[nodiscard]] bool something_new(Poll p) const {
    if (p == Poll::empty)
      return shared_->header.write_index.load(std::memory_order_seq_cst) > read_index_;
    const std::uint64_t seq =
        shared_->slots[read_index_ & kSlotMask].seq.load(std::memory_order_seq_cst);
    return seq == published(read_index_) || position_plus_one(seq) > read_index_ + 1;
  }

  /// CAN_RAW's receive rules: error frames by class mask, data and remote frames by filter.
  bool accept(const can_frame& frame) {
    if ((frame.can_id & CAN_ERR_FLAG) != 0U) {
      if ((frame.can_id & CAN_ERR_MASK & error_mask_) == 0U) return false;
      ++stats_.error_frames;
      return true;
    }
    for (const can_filter& f : filters_) {
      if (matches(f, frame.can_id)) {
        ++stats_.received;
        return true;
      }
    }
    return false;
  }

  static bool matches(const can_filter& filter, canid_t can_id) {
    canid_t mask = filter.can_mask;
    if ((mask & CAN_ERR_FLAG) != 0U) return false;  // an error-frame filter in CAN_RAW
    const bool inverted = (filter.can_id & CAN_INV_FILTER) != 0U;
    // As the kernel (af_can.c): a mask that tests CAN_EFF_FLAG with an SFF id matches SFF only.
    if ((mask & CAN_EFF_FLAG) != 0U && (filter.can_id & CAN_EFF_FLAG) == 0U)
      mask &= (CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG);
    const bool match = (can_id & mask) == (filter.can_id & mask);
    return inverted ? !match : match;
  }

  std::string url_;
  std::shared_ptr<Mapping> mapping_;
  Shared* shared_;
  std::uint64_t node_ = 0;
  std::uint64_t read_index_ = 0;
  std::int64_t stall_since_ = -1;  // CLOCK_MONOTONIC [ns] since the slot at read_index_ is pending
  std::vector<can_filter> filters_;
  can_err_mask_t error_mask_ = 0;
  BusStats stats_;
  char last_error_[256] = "";
};

}  // namespace

std::string virtual_bus_object(std::string_view name) {
  std::string object = "/mrroc-can-";
  if (const char* space = std::getenv(kVirtualBusNamespaceVariable);
      space != nullptr && *space != '\0') {
    object += space;
    object += '.';
  }
  object += name;
  return object;
}

std::unique_ptr<Bus> open_virtual_bus(std::string_view url, std::string_view name) {
  return std::make_unique<VirtualBus>(std::string(url), map_bus(url, name));
}

void abandon_claim_for_test(Bus& bus, bool marked) {
  auto* node = dynamic_cast<VirtualBus*>(&bus);
  if (node == nullptr) throw Error(bus.url() + ": abandon_claim_for_test needs a virtual bus");
  node->abandon_claim(marked);
}

}  // namespace mrroc::can::detail
