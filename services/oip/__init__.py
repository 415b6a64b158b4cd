"""The Open Inference Protocol (KServe "v2") beside `/v1`, as Triton and KServe speak it: any v2
client (tritonclient, KServe's) can ask coexist for an action with its default arguments.

| v2                                   | REST                                   | gRPC (`inference.GRPCInferenceService`) |
|--------------------------------------|----------------------------------------|-----------------------------------------|
| server live / ready                  | `GET /v2/health/live`, `/v2/health/ready` | `ServerLive`, `ServerReady`          |
| server metadata                      | `GET /v2`                              | `ServerMetadata`                        |
| model metadata / ready               | `GET /v2/models/{env}`, `.../ready`    | `ModelMetadata`, `ModelReady`           |
| infer (= `POST /v1/act`, B rows)     | `POST /v2/models/{env}/infer`          | `ModelInfer`                            |
| model configuration (Triton)         | `GET /v2/models/{env}/config`          | `ModelConfig`                           |
| statistics (Triton)                  | `GET /v2/models[/{env}]/stats`         | `ModelStatistics`                       |
| repository index (Triton)            | `POST /v2/repository/index`            | `RepositoryIndex`                       |

A model is an environment (`particle`, `cooking`); its one version is "1" (the model routes also
take `/versions/1`; any other version is 404 / NOT_FOUND). `core` maps a v2 request to the
engine's `ActRequest` and back and holds the facts behind the other routes; `rest` and
`grpc_servicer` only translate.
"""
