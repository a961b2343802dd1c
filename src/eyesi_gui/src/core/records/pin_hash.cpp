#include "eyesi_gui/records/pin_hash.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/rand.h>

#include "eyesi_gui/records/store.h"

namespace eyesi_gui::records {
namespace {

std::vector<unsigned char> pbkdf2(const std::string& pin, const std::vector<unsigned char>& salt, int iterations) {
  std::vector<unsigned char> out(kPinHashBytes);
  if (PKCS5_PBKDF2_HMAC(pin.data(), static_cast<int>(pin.size()), salt.data(), static_cast<int>(salt.size()),
                        iterations, EVP_sha256(), static_cast<int>(out.size()), out.data()) != 1) {
    throw StoreError("PBKDF2-HMAC-SHA256 failed (OpenSSL)");
  }
  return out;
}

}  // namespace

PinHash hashPin(const std::string& pin, int iterations) {
  PinHash result;
  result.salt.resize(kPinSaltBytes);
  if (RAND_bytes(result.salt.data(), static_cast<int>(result.salt.size())) != 1) {
    throw StoreError("no random salt for the PIN (OpenSSL RAND_bytes failed)");
  }
  result.iterations = iterations;
  result.hash = pbkdf2(pin, result.salt, iterations);
  return result;
}

bool verifyPin(const std::string& pin, const PinHash& stored) {
  // A row with a damaged hash or iteration count must not turn into "any PIN matches".
  if (stored.hash.size() != static_cast<std::size_t>(kPinHashBytes) || stored.salt.empty() || stored.iterations <= 0) {
    return false;
  }
  const std::vector<unsigned char> computed = pbkdf2(pin, stored.salt, stored.iterations);
  // Constant time: the comparison must not tell an attacker how many leading bytes were right.
  return CRYPTO_memcmp(computed.data(), stored.hash.data(), computed.size()) == 0;
}

}  // namespace eyesi_gui::records
