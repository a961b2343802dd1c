#pragma once
// Messages from fuzz bytes as a subscriber gets them: ros::serialization of the wire format, no master. The input
// of the message targets is a sequence of frames [u8 kind][u16 length][length bytes of a serialised message]; a
// frame whose bytes do not deserialise (overrun, absurd array length) is dropped like a message roscpp cannot read.

#include <ros/serialization.h>

#include <new>
#include <stdexcept>

#include "fuzz_target.h"

namespace vrm_fuzz {

struct Frame {
  std::uint8_t kind = 0;
  const std::uint8_t* data = nullptr;
  std::uint32_t size = 0;
};

inline bool nextFrame(Bytes& in, Frame* frame) {
  if (in.remaining() < 3) return false;
  frame->kind = in.take<std::uint8_t>();
  const std::uint16_t length = in.take<std::uint16_t>();
  frame->data = in.cursor();
  frame->size = static_cast<std::uint32_t>(length < in.remaining() ? length : in.remaining());
  in.skip(frame->size);
  return true;
}

template <typename M>
bool deserialize(const Frame& frame, M* message) {
  try {
    ros::serialization::IStream stream(const_cast<std::uint8_t*>(frame.data), frame.size);
    ros::serialization::deserialize(stream, *message);
    return true;
  } catch (const ros::serialization::StreamOverrunException&) {
  } catch (const std::bad_alloc&) {  // a length prefix of gigabytes (see scripts/fuzz.sh: max_allocation_size_mb)
  } catch (const std::length_error&) {
  }
  return false;
}

// Appends one frame (for seeds and tests).
template <typename M>
void appendFrame(std::uint8_t kind, const M& message, std::vector<std::uint8_t>* out) {
  const std::uint32_t length = ros::serialization::serializationLength(message);
  std::vector<std::uint8_t> bytes(length);
  ros::serialization::OStream stream(bytes.data(), length);
  ros::serialization::serialize(stream, message);
  out->push_back(kind);
  out->push_back(static_cast<std::uint8_t>(length & 0xff));
  out->push_back(static_cast<std::uint8_t>((length >> 8) & 0xff));
  out->insert(out->end(), bytes.begin(), bytes.end());
}

}  // namespace vrm_fuzz
