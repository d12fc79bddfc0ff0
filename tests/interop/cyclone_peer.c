// A Cyclone DDS participant that knows lodestone only through lode_msgs.idl (compiled by
// Cyclone's idlc): what a user of another DDS implementation would write. It
//   1. reads lode/signals and prints each topic's metadata and key,
//   2. reads one signal topic and the state topic, writing each sample as `lode echo`
//      prints it (so the two can be compared line by line, by cycle), and checks that
//      every sample arrives as plain CDR (XCDR1, little endian),
//   3. sends a `set` and then a `get` on lode/<pipeline>/command and prints the replies,
//   4. prints "awaiting-dispose" and waits until every metadata instance it read is
//      disposed (the pipeline stopped): a dispose carries only the key hash, which Cyclone
//      can turn back into the key only when the key is at most 16 bytes.
// usage: cyclone_peer DOMAIN PIPELINE SIGNAL_TOPIC SAMPLES OUTDIR BLOCK PARAMETER VALUE
// Exit 0 when every step succeeded; 1 with the failed step on stderr. The participant
// takes its transport from CYCLONEDDS_URI (docs/telemetry.md).
#include <inttypes.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#define XXH_INLINE_ALL  // the header alone: no library to link
#include <xxhash.h>

#include "lode_msgs.h"

enum { kMaxTopics = 64, kBatch = 64 };
static const dds_duration_t kPoll = DDS_MSECS(1);

static const char* kClient = "cyclone-peer";  // also the participant's name (allow lists)

struct known_topic {
  uint64_t id;
  char name[256];
  bool gone;  // disposed, or its writer left without disposing it
};
static struct known_topic topics[kMaxTopics];
static int topic_count;

static int fail(const char* what) {
  fprintf(stderr, "cyclone_peer: %s\n", what);
  return 1;
}

static dds_qos_t* qos(dds_reliability_kind_t reliability, dds_durability_kind_t durability, int32_t depth) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, reliability, DDS_SECS(1));
  dds_qset_durability(q, durability);
  dds_qset_history(q, depth > 0 ? DDS_HISTORY_KEEP_LAST : DDS_HISTORY_KEEP_ALL, depth > 0 ? depth : 0);
  // lodestone's types are @final and lodestone writes and reads plain CDR only.
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(q, 1, &xcdr1);
  return q;
}

static dds_entity_t endpoint(dds_entity_t participant, const dds_topic_descriptor_t* type, const char* name,
                             dds_qos_t* q, bool writer) {
  const dds_entity_t topic = dds_create_topic(participant, type, name, NULL, NULL);
  const dds_entity_t e = topic < 0 ? topic : writer ? dds_create_writer(participant, topic, q, NULL)
                                                     : dds_create_reader(participant, topic, q, NULL);
  dds_delete_qos(q);
  if (e < 0) fprintf(stderr, "cyclone_peer: %s on '%s': %s\n", writer ? "writer" : "reader", name, dds_strretcode(e));
  return e;
}

static void print_values(FILE* out, const dds_sequence_double* s) {
  for (uint32_t i = 0; i < s->_length; ++i) fprintf(out, " %.17g", s->_buffer[i]);
}

// Metadata: remember each topic by key; count the disposes of the ones seen.
static void take_infos(dds_entity_t reader, int* disposed, int* gone) {
  void* samples[kBatch] = {NULL};
  dds_sample_info_t infos[kBatch];
  const int n = dds_take(reader, samples, infos, kBatch, kBatch);
  for (int i = 0; i < n; ++i) {
    const lode_msg_SignalInfo* s = samples[i];
    int k = 0;
    while (k < topic_count && topics[k].id != s->topic_id) ++k;  // the key is filled in either case
    if (infos[i].valid_data) {
      if (k == topic_count && topic_count < kMaxTopics) {
        topics[k].id = s->topic_id;
        snprintf(topics[k].name, sizeof topics[k].name, "%s", s->topic);
        ++topic_count;
      }
      const uint64_t expected = XXH64(s->topic, strlen(s->topic), 0);
      printf("info %016" PRIx64 " %s %s %s key=%s", s->topic_id, s->topic, s->kind,
             s->reliable ? "reliable" : "best_effort", s->topic_id == expected ? "xxh64" : "WRONG");
      for (uint32_t e = 0; e < s->names._length; ++e) printf(" %s[%s]", s->names._buffer[e], s->units._buffer[e]);
      printf("\n");
    } else if (k < topic_count && !topics[k].gone) {
      const bool is_disposed = infos[i].instance_state == DDS_IST_NOT_ALIVE_DISPOSED;
      printf("%s %016" PRIx64 " %s\n", is_disposed ? "disposed" : "not_alive_no_writers", s->topic_id, topics[k].name);
      topics[k].gone = true;
      ++*gone;
      if (is_disposed) ++*disposed;
    }
  }
  if (n > 0) dds_return_loan(reader, samples, n);
  fflush(stdout);
}

// A signal or state sample, taken serialized so that its encapsulation can be checked, then
// written as `lode echo` prints it. Returns 1 per sample, -1 on a foreign encapsulation.
static int take_serialized(dds_entity_t reader, const dds_topic_descriptor_t* type, bool state, FILE* out) {
  struct ddsi_serdata* data = NULL;
  dds_sample_info_t info;
  if (dds_takecdr(reader, &data, 1, &info, DDS_ANY_STATE) != 1) return 0;
  unsigned char header[4];
  ddsi_serdata_to_ser(data, 0, sizeof header, header);
  const unsigned encapsulation = (unsigned)(header[0] << 8 | header[1]);
  int result = 0;
  if (info.valid_data && encapsulation != 0x0001) {  // CDR_LE; XCDR2 would be 0x0007 or 0x0009
    fprintf(stderr, "cyclone_peer: a sample with encapsulation 0x%04x, not CDR_LE (0x0001)\n", encapsulation);
    result = -1;
  } else if (info.valid_data) {
    void* sample = dds_alloc(type->m_size);
    ddsi_serdata_to_sample(data, sample, NULL, NULL);
    if (state) {
      const lode_msg_StageState* s = sample;
      fprintf(out, "%" PRIu64 " %.9f", s->cycle, (double)s->stamp_ns * 1e-9);
      print_values(out, &s->pose);
      print_values(out, &s->twist);
      print_values(out, &s->covariance);
    } else {
      const lode_msg_SignalSample* s = sample;
      fprintf(out, "%" PRIu64 " %.9f", s->cycle, (double)s->stamp_ns * 1e-9);
      print_values(out, &s->values);
    }
    fprintf(out, "\n");
    dds_sample_free(sample, type, DDS_FREE_ALL);
    result = 1;
  }
  ddsi_serdata_unref(data);
  return result;
}

// One command, answered by the reply with our client name and id (or NULL after the timeout).
static lode_msg_Reply* command(dds_entity_t writer, dds_entity_t replies, uint64_t id, const char* kind,
                               const char* block, const char* name, const char* value) {
  lode_msg_Command c = {.client = (char*)kClient, .id = id, .kind = (char*)kind, .block = (char*)block,
                        .name = (char*)name, .value = (char*)value, .plugin = ""};
  if (dds_write(writer, &c) != DDS_RETCODE_OK) return NULL;
  for (dds_time_t deadline = dds_time() + DDS_SECS(20); dds_time() < deadline; dds_sleepfor(kPoll)) {
    void* samples[1] = {NULL};
    dds_sample_info_t info;
    if (dds_take(replies, samples, &info, 1, 1) != 1) continue;
    const lode_msg_Reply* r = samples[0];
    lode_msg_Reply* mine = NULL;
    if (info.valid_data && r->id == id && strcmp(r->client, kClient) == 0) {
      mine = dds_alloc(sizeof *mine);
      mine->ok = r->ok;
      mine->message = dds_string_dup(r->message);
      mine->value = dds_string_dup(r->value);
    }
    dds_return_loan(replies, samples, 1);
    if (mine) return mine;
  }
  return NULL;
}

int main(int argc, char** argv) {
  if (argc != 9) return fail("usage: cyclone_peer DOMAIN PIPELINE SIGNAL_TOPIC SAMPLES OUTDIR BLOCK PARAMETER VALUE");
  const dds_domainid_t domain = (dds_domainid_t)atoi(argv[1]);
  const char *pipeline = argv[2], *signal_topic = argv[3], *outdir = argv[5];
  const int wanted = atoi(argv[4]);
  const char *block = argv[6], *parameter = argv[7], *value = argv[8];

  dds_qos_t* participant_qos = dds_create_qos();
  dds_qset_entity_name(participant_qos, kClient);
  const dds_entity_t participant = dds_create_participant(domain, participant_qos, NULL);
  dds_delete_qos(participant_qos);
  if (participant < 0) return fail(dds_strretcode(participant));

  char name[512], path[512];
  // The QoS docs/telemetry.md lists per topic: what each lodestone writer offers.
  const dds_entity_t info_reader = endpoint(participant, &lode_msg_SignalInfo_desc, "lode/signals",
                                            qos(DDS_RELIABILITY_RELIABLE, DDS_DURABILITY_TRANSIENT_LOCAL, 1), false);
  const dds_entity_t signal_reader = endpoint(participant, &lode_msg_SignalSample_desc, signal_topic,
                                              qos(DDS_RELIABILITY_BEST_EFFORT, DDS_DURABILITY_VOLATILE, 1000), false);
  snprintf(name, sizeof name, "lode/%s/state", pipeline);
  const dds_entity_t state_reader = endpoint(participant, &lode_msg_StageState_desc, name,
                                             qos(DDS_RELIABILITY_BEST_EFFORT, DDS_DURABILITY_VOLATILE, 1000), false);
  snprintf(name, sizeof name, "lode/%s/reply", pipeline);
  const dds_entity_t reply_reader = endpoint(participant, &lode_msg_Reply_desc, name,
                                             qos(DDS_RELIABILITY_RELIABLE, DDS_DURABILITY_TRANSIENT_LOCAL, 256), false);
  snprintf(name, sizeof name, "lode/%s/command", pipeline);
  const dds_entity_t command_writer = endpoint(participant, &lode_msg_Command_desc, name,
                                               qos(DDS_RELIABILITY_RELIABLE, DDS_DURABILITY_VOLATILE, 0), true);
  if (info_reader < 0 || signal_reader < 0 || state_reader < 0 || reply_reader < 0 || command_writer < 0) {
    dds_delete(participant);
    return 1;
  }

  int status = 0, disposed = 0, gone = 0;
  snprintf(path, sizeof path, "%s/signal.txt", outdir);
  FILE* signal_out = fopen(path, "w");
  snprintf(path, sizeof path, "%s/state.txt", outdir);
  FILE* state_out = fopen(path, "w");
  if (!signal_out || !state_out) {
    dds_delete(participant);
    return fail("cannot write into OUTDIR");
  }

  // 1 and 2: metadata, and SAMPLES signal samples plus one state sample per eight of them.
  int signals = 0, states = 0;
  const dds_time_t collect_deadline = dds_time() + DDS_SECS(60);
  while (status == 0 && (signals < wanted || states < wanted / 8 || topic_count == 0)) {
    if (dds_time() > collect_deadline) {
      fprintf(stderr, "cyclone_peer: after 60 s: %d metadata, %d signal and %d state samples\n", topic_count,
              signals, states);
      status = 1;
      break;
    }
    take_infos(info_reader, &disposed, &gone);
    int got;
    while ((got = take_serialized(signal_reader, &lode_msg_SignalSample_desc, false, signal_out)) > 0) signals += got;
    if (got < 0) status = 1;
    while ((got = take_serialized(state_reader, &lode_msg_StageState_desc, true, state_out)) > 0) states += got;
    if (got < 0) status = 1;
    dds_sleepfor(kPoll);
  }
  fclose(signal_out);
  fclose(state_out);
  if (status == 0) printf("collected %d signal and %d state samples, encapsulation CDR_LE\n", signals, states);

  // 3: set, then get, as lodestone's own clients do.
  if (status == 0) {
    dds_publication_matched_status_t matched = {0};
    for (dds_time_t deadline = dds_time() + DDS_SECS(20); matched.current_count == 0 && dds_time() < deadline;
         dds_sleepfor(DDS_MSECS(10)))
      dds_get_publication_matched_status(command_writer, &matched);
    lode_msg_Reply* set = matched.current_count > 0 ? command(command_writer, reply_reader, 1, "set", block, parameter, value)
                                                    : NULL;
    lode_msg_Reply* get = set ? command(command_writer, reply_reader, 2, "get", block, parameter, "") : NULL;
    if (set) printf("reply set %s %s\n", set->ok ? "ok" : "refused", set->message);
    if (get) printf("reply get %s value=%s\n", get->ok ? "ok" : "refused", get->value);
    if (!set || !get) status = fail(matched.current_count == 0 ? "the command reader never matched"
                                                                : "no reply within 20 s");
    if (set) dds_sample_free(set, &lode_msg_Reply_desc, DDS_FREE_ALL);
    if (get) dds_sample_free(get, &lode_msg_Reply_desc, DDS_FREE_ALL);
  }

  // 4: the pipeline is stopped by whoever runs us; its metadata must be disposed.
  if (status == 0) {
    printf("awaiting-dispose\n");
    fflush(stdout);
    const dds_time_t deadline = dds_time() + DDS_SECS(60);
    while (gone < topic_count && dds_time() < deadline) {
      take_infos(info_reader, &disposed, &gone);
      dds_sleepfor(kPoll);
    }
    printf("disposed %d of %d metadata instances\n", disposed, topic_count);
    if (disposed < topic_count)
      status = fail(gone == topic_count ? "metadata instances went with their writer, never disposed"
                                        : "not every metadata instance was disposed within 60 s");
  }
  fflush(stdout);
  dds_delete(participant);
  return status;
}
