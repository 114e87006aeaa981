#pragma once
/// @file
/// LCM hands messages between threads through GLib queues whose locks ThreadSanitizer cannot
/// see (GLib is not instrumented). These annotations tell it what the queue guarantees: a
/// message published before it is dispatched happens-before its handler. No-ops in other builds.

#if defined(__SANITIZE_THREAD__)
extern "C" void __tsan_acquire(void* address);
extern "C" void __tsan_release(void* address);
#endif

namespace mrroc::comm::detail {

inline char& lcm_handoff_token() {
  static char token;
  return token;
}

/// Call after handing a message to LCM (publish).
inline void published() {
#if defined(__SANITIZE_THREAD__)
  __tsan_release(&lcm_handoff_token());
#endif
}

/// Call at the start of every LCM handler.
inline void dispatched() {
#if defined(__SANITIZE_THREAD__)
  __tsan_acquire(&lcm_handoff_token());
#endif
}

/// Decodes an LCM message from a received buffer after marking the hand-off.
/// Returns false (and leaves `out` unspecified) when the bytes do not decode. Never throws: an
/// exception would leave the LCM handler and end the process (the generated decoders allocate).
template <class Msg, class Buffer>
bool decode_received(const Buffer* buffer, Msg& out) noexcept {
  dispatched();
  try {
    return out.decode(buffer->data, 0, static_cast<int>(buffer->data_size)) >= 0;
  } catch (...) {
    return false;
  }
}

}  // namespace mrroc::comm::detail
