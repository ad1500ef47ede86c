#include "superdyna/core/bounded_queue.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <map>
#include <memory>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

namespace superdyna {
namespace {

// Waits (polling) until `done` holds; the tests never assert on the time this takes.
template <typename Condition>
void waitFor(Condition done) {
  while (!done())
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

TEST(BoundedQueue, IsFifo) {
  BoundedQueue<int> queue(3);
  EXPECT_EQ(queue.capacity(), 3u);
  EXPECT_TRUE(queue.push(1));
  EXPECT_TRUE(queue.push(2));
  EXPECT_TRUE(queue.push(3));
  EXPECT_EQ(queue.size(), 3u);
  EXPECT_EQ(queue.pop(), 1);
  EXPECT_EQ(queue.pop(), 2);
  EXPECT_TRUE(queue.push(4));
  EXPECT_EQ(queue.pop(), 3);
  EXPECT_EQ(queue.pop(), 4);
  EXPECT_EQ(queue.size(), 0u);
}

TEST(BoundedQueue, RejectsZeroCapacity) {
  EXPECT_THROW(BoundedQueue<int>(0), std::invalid_argument);
}

TEST(BoundedQueue, MovesMoveOnlyItems) {
  BoundedQueue<std::unique_ptr<int>> queue(1);
  EXPECT_TRUE(queue.push(std::make_unique<int>(7)));
  const std::optional<std::unique_ptr<int>> item = queue.pop();
  ASSERT_TRUE(item && *item);
  EXPECT_EQ(**item, 7);
}

TEST(BoundedQueue, PushWaitsForRoom) {
  BoundedQueue<int> queue(2);
  std::atomic<int> pushed{0};
  std::thread producer([&] {
    for (int i = 0; i < 3; ++i) {
      queue.push(i);
      ++pushed;
    }
  });
  waitFor([&] { return pushed.load() >= 2; });
  EXPECT_EQ(queue.size(), 2u);  // the third push waits for a pop
  EXPECT_EQ(queue.pop(), 0);
  producer.join();
  EXPECT_EQ(pushed.load(), 3);
  EXPECT_EQ(queue.pop(), 1);
  EXPECT_EQ(queue.pop(), 2);
}

TEST(BoundedQueue, CloseDrainsQueuedItemsThenEnds) {
  BoundedQueue<int> queue(4);
  queue.push(1);
  queue.push(2);
  queue.close();
  queue.close();  // idempotent
  EXPECT_TRUE(queue.closed());
  EXPECT_FALSE(queue.push(3));
  EXPECT_EQ(queue.pop(), 1);
  EXPECT_EQ(queue.pop(), 2);
  EXPECT_EQ(queue.pop(), std::nullopt);
  EXPECT_EQ(queue.pop(), std::nullopt);
}

TEST(BoundedQueue, CloseWakesABlockedConsumer) {
  BoundedQueue<int> queue(1);
  std::optional<int> result = 42;
  std::thread consumer([&] { result = queue.pop(); });
  queue.close();
  consumer.join();
  EXPECT_EQ(result, std::nullopt);
}

TEST(BoundedQueue, CloseWakesABlockedProducer) {
  BoundedQueue<int> queue(1);
  queue.push(1);
  std::atomic<bool> started{false};
  bool accepted = true;
  std::thread producer([&] {
    started = true;
    accepted = queue.push(2);
  });
  waitFor([&] { return started.load(); });
  queue.close();
  producer.join();
  EXPECT_FALSE(accepted);
  EXPECT_EQ(queue.pop(), 1);  // the item queued before close() is still served
  EXPECT_EQ(queue.pop(), std::nullopt);
}

TEST(BoundedQueue, ClearRemovesItemsAndMakesRoom) {
  BoundedQueue<int> queue(2);
  queue.push(1);
  queue.push(2);
  std::thread producer([&] { queue.push(3); });
  waitFor([&] { return queue.size() == 2; });
  const std::size_t removed = queue.clear();
  producer.join();
  // The blocked push may have got in before or after the clear.
  EXPECT_TRUE(removed == 2u || removed == 3u);
  EXPECT_EQ(queue.size(), 3u - removed);
}

TEST(BoundedQueue, ManyProducersAndConsumersDeliverEveryItemOnceInOrder) {
  constexpr int kProducers = 4, kConsumers = 3, kItemsEach = 2000;
  BoundedQueue<std::pair<int, int>> queue(5);  // (producer, sequence number)
  std::vector<std::vector<std::pair<int, int>>> received(kConsumers);
  std::vector<std::thread> consumers;
  for (int c = 0; c < kConsumers; ++c) {
    consumers.emplace_back([&, c] {
      while (const auto item = queue.pop())
        received[static_cast<std::size_t>(c)].push_back(*item);
    });
  }
  std::vector<std::thread> producers;
  for (int p = 0; p < kProducers; ++p) {
    producers.emplace_back([&, p] {
      for (int i = 0; i < kItemsEach; ++i)
        EXPECT_TRUE(queue.push({p, i}));
    });
  }
  for (std::thread& t : producers)
    t.join();
  queue.close();  // consumers drain what is left, then see the end
  for (std::thread& t : consumers)
    t.join();

  std::map<int, std::vector<int>> per_producer;
  for (const auto& items : received) {
    std::map<int, int> last;  // each consumer sees each producer's items in push order
    for (const auto& [p, i] : items) {
      const auto it = last.find(p);
      if (it != last.end()) {
        EXPECT_LT(it->second, i);
      }
      last[p] = i;
      per_producer[p].push_back(i);
    }
  }
  ASSERT_EQ(per_producer.size(), static_cast<std::size_t>(kProducers));
  for (auto& [p, items] : per_producer) {
    std::sort(items.begin(), items.end());
    ASSERT_EQ(items.size(), static_cast<std::size_t>(kItemsEach)) << "producer " << p;
    for (int i = 0; i < kItemsEach; ++i)
      EXPECT_EQ(items[static_cast<std::size_t>(i)], i);
  }
}

}  // namespace
}  // namespace superdyna
