#pragma once
// A real OpenIGTLink peer for tests: libOpenIGTLink's own client socket over loopback, as a
// tracker or 3D Slicer would connect to the device.

#include <igtlClientSocket.h>
#include <igtlMessageHeader.h>
#include <igtlTransformMessage.h>

#include <gtest/gtest.h>

#include <csignal>
#include <cstring>
#include <string>
#include <vector>

namespace touchstone::testing {

// igtl::Socket::Send does not pass MSG_NOSIGNAL: a write to a connection the device has closed
// must not kill the test process.
inline const bool sigpipe_ignored = [] {
  std::signal(SIGPIPE, SIG_IGN);
  return true;
}();

/// A client connected to the device, built from libOpenIGTLink's ClientSocket.
class Peer {
 public:
  explicit Peer(int port) : socket_(igtl::ClientSocket::New()) {
    connected_ = socket_->ConnectToServer("127.0.0.1", port) == 0;
    if (connected_) socket_->SetReceiveTimeout(2000);  // ms: a broken device fails the test, never hangs it
  }
  bool connected() const { return connected_; }

  void send_bytes(const std::vector<unsigned char>& bytes) {
    socket_->Send(bytes.data(), static_cast<int>(bytes.size()));
  }
  void send(igtl::MessageBase* message) {
    message->SetTimeStamp(0, 0);  // libOpenIGTLink leaves it uninitialized
    message->Pack();
    socket_->Send(message->GetPackPointer(), message->GetPackSize());
  }
  /// The packed bytes of a message (to corrupt before sending).
  static std::vector<unsigned char> packed(igtl::MessageBase* message) {
    message->SetTimeStamp(0, 0);
    message->Pack();
    const auto* begin = static_cast<const unsigned char*>(message->GetPackPointer());
    return {begin, begin + message->GetPackSize()};
  }
  void send_transform(const igtl::Matrix4x4& matrix, const char* device_name = "Tracker") {
    igtl::TransformMessage::Pointer message = igtl::TransformMessage::New();
    message->SetDeviceName(device_name);
    igtl::Matrix4x4 copy;
    std::memcpy(copy, matrix, sizeof copy);
    message->SetMatrix(copy);
    send(message);
  }
  void close() { socket_->CloseSocket(); }

  /// The next message of type M (messages of other types are skipped), or null when the
  /// stream ends or stays silent for 2 s.
  template <class M>
  typename M::Pointer receive(const std::string& type) {
    for (;;) {
      igtl::MessageHeader::Pointer header = igtl::MessageHeader::New();
      header->InitPack();
      if (socket_->Receive(header->GetPackPointer(), header->GetPackSize()) != header->GetPackSize()) return nullptr;
      header->Unpack();
      if (type != header->GetDeviceType()) {
        if (header->GetBodySizeToRead() > 0 && socket_->Skip(header->GetBodySizeToRead(), 1) <= 0) return nullptr;
        continue;
      }
      typename M::Pointer message = M::New();
      message->SetMessageHeader(header);
      message->AllocatePack();
      if (socket_->Receive(message->GetPackBodyPointer(), message->GetPackBodySize()) != message->GetPackBodySize())
        return nullptr;
      if (!(message->Unpack(1) & igtl::MessageHeader::UNPACK_BODY)) {
        ADD_FAILURE() << type << " from the device failed its CRC check";
        return nullptr;
      }
      return message;
    }
  }

 private:
  igtl::ClientSocket::Pointer socket_;
  bool connected_ = false;
};

}  // namespace touchstone::testing
