// Per-address connection slots and the fair scheduler (see admission.hpp).
#include "server/admission.hpp"

#include <boost/asio/post.hpp>
#include <boost/asio/write.hpp>

namespace mtlod::server {

std::string remote_address(const boost::asio::ip::tcp::socket& socket) {
  boost::system::error_code ec;
  const auto endpoint = socket.remote_endpoint(ec);
  return ec ? std::string() : endpoint.address().to_string();
}

void refuse_socket(boost::asio::ip::tcp::socket socket, std::string bytes) {
  auto held = std::make_shared<std::pair<boost::asio::ip::tcp::socket, std::string>>(std::move(socket),
                                                                                     std::move(bytes));
  boost::asio::async_write(held->first, boost::asio::buffer(held->second),
                           [held](boost::system::error_code, std::size_t) {
                             boost::system::error_code ignored;
                             held->first.shutdown(boost::asio::ip::tcp::socket::shutdown_both, ignored);
                             held->first.close(ignored);
                           });
}

AddressTable::Slot& AddressTable::Slot::operator=(Slot&& other) noexcept {
  if (this != &other) {
    reset();
    table_ = other.table_;
    address_ = std::move(other.address_);
    other.table_ = nullptr;
  }
  return *this;
}

void AddressTable::Slot::reset() {
  if (table_) table_->release(address_);
  table_ = nullptr;
}

AddressTable::Slot AddressTable::acquire(const std::string& address) {
  Slot slot;
  std::lock_guard lock(mutex_);
  std::uint32_t& held = held_[address];
  if (cap_ != 0 && held >= cap_) {
    if (held == 0) held_.erase(address);
    return slot;
  }
  ++held;
  slot.table_ = this;
  slot.address_ = address;
  return slot;
}

std::uint32_t AddressTable::held(const std::string& address) const {
  std::lock_guard lock(mutex_);
  const auto it = held_.find(address);
  return it == held_.end() ? 0 : it->second;
}

void AddressTable::release(const std::string& address) {
  std::lock_guard lock(mutex_);
  const auto it = held_.find(address);
  if (it != held_.end() && --it->second == 0) held_.erase(it);
}

bool MemoryCeiling::reserve(std::uint64_t bytes) {
  std::uint64_t held = held_.load(std::memory_order_relaxed);
  do {
    if (held + bytes > limit_ || held + bytes < held) return false;
  } while (!held_.compare_exchange_weak(held, held + bytes, std::memory_order_relaxed));
  return true;
}

void FairScheduler::submit(const std::string& key, std::function<void()> job) {
  std::unique_lock lock(mutex_);
  auto& queue = waiting_[key];
  if (queue.empty()) turns_.push_back(key);
  queue.push_back(std::move(job));
  ++waiting_count_;
  dispatch(lock);
}

std::size_t FairScheduler::waiting() const {
  std::lock_guard lock(mutex_);
  return waiting_count_;
}

void FairScheduler::dispatch(std::unique_lock<std::mutex>&) {
  while (running_ < slots_ && !turns_.empty()) {
    const std::string key = std::move(turns_.front());
    turns_.pop_front();
    auto it = waiting_.find(key);
    std::function<void()> job = std::move(it->second.front());
    it->second.pop_front();
    if (it->second.empty()) {
      waiting_.erase(it);
    } else {
      turns_.push_back(key);  // its next job waits for every other key's turn
    }
    --waiting_count_;
    ++running_;
    boost::asio::post(pool_, [this, job = std::move(job)] {
      job();
      finished();
    });
  }
}

void FairScheduler::finished() {
  std::unique_lock lock(mutex_);
  --running_;
  dispatch(lock);
}

}  // namespace mtlod::server
